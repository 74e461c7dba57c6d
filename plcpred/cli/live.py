"""``plcpred serve`` (the emulated machine as an OPC UA server) and ``plcpred watch``
(the running machine over OPC UA, recorded and compared with the prediction)."""
from __future__ import annotations

import asyncio
import logging
import sys
from datetime import UTC, datetime

from ..errors import PlcpredError
from ..live import LiveError, Twin, live_settings, machine_signals, serve, watch
from ..machine import load_machine
from ..output import check_out_dir
from ..sequencer import parse_horizon
from .common import exit_code


def _seconds(text: str | None, option: str) -> float | None:
    if text is None:
        return None
    try:
        return parse_horizon(text) / 1e9
    except ValueError:
        raise LiveError(f"{option}: cannot read {text!r}: write e.g. 90s, 30min or "
                        "1h") from None


def _epoch(text: str | None) -> datetime | None:
    if text is None:
        return None
    try:
        t = datetime.fromisoformat(text.strip())
    except ValueError:
        raise LiveError(f"--epoch: cannot read {text!r}: write an ISO 8601 time such as "
                        "2026-11-24T08:00:00Z") from None
    return t if t.tzinfo is not None else t.replace(tzinfo=UTC)


def _quiet_asyncua() -> None:
    """asyncua logs every dropped connection as a traceback; watch reports them itself."""
    logging.getLogger("asyncua").setLevel(logging.CRITICAL)


def cmd_serve(args) -> int:
    _quiet_asyncua()
    try:
        horizon_s = _seconds(args.horizon, "--horizon")
        twin = Twin(args.machine, horizon_s, truth=args.truth,
                    truth_at_s=_seconds(args.truth_at, "--truth-at") or 0.0, seed=args.seed,
                    program=args.program)
        result = asyncio.run(serve(twin, args.endpoint, speed=args.speed,
                                   epoch=_epoch(args.epoch), history=args.history,
                                   report=lambda line: print(line, flush=True)))
    except PlcpredError as e:
        print(f"plcpred: error: {e}", file=sys.stderr)
        return exit_code(e) if not isinstance(e, LiveError) else 2
    print(f"served {result.served_s:g} s of machine time ({result.values_written} values); "
          "horizon reached", flush=True)
    return 0


def cmd_watch(args) -> int:
    _quiet_asyncua()
    try:
        out = check_out_dir(args.out)
        machine = load_machine(args.machine)
        settings = live_settings(
            machine, endpoint=args.endpoint, cycle_signal=args.cycle_signal,
            window_s=_seconds(args.window, "--window"),
            rotate_s=_seconds(args.rotate, "--rotate"),
            gap_alarm_percent=args.gap_alarm, gap_alarm_cycles=args.gap_cycles,
            learn_cycles=args.learn_cycles,
            diagnose_every_s=_seconds(args.diagnose_every, "--diagnose-every"),
            prometheus=args.prometheus, plot=args.plot,
            idle_limit_l_min=args.idle_limit, publishing_ms=args.publishing_ms)
        _check_settings(machine, settings)
        duration_s = _seconds(args.duration, "--duration")
        print(f"watching {machine.name} at {settings.endpoint} into {out}"
              + (f" for {duration_s:g} s" if duration_s else " (Ctrl-C ends)"), flush=True)
        result = asyncio.run(watch(machine, out, settings, duration_s=duration_s,
                                   report=lambda line: print(line, flush=True)))
    except PlcpredError as e:
        print(f"plcpred: error: {e}", file=sys.stderr)
        return exit_code(e) if not isinstance(e, LiveError) else 2
    print(f"{result.cycles} cycles compared, {result.readings} readings, {result.changes} "
          f"changes, {len(result.gaps)} gaps, {len(result.alarms)} alarm events; wrote "
          + (", ".join(str(p) for p in result.files) or "no complete segment"))
    return 0


def _check_settings(machine, s) -> None:
    """Options whose ranges the machine file's reader checks for ``[live]``."""
    if s.cycle_signal is not None and s.cycle_signal not in machine_signals(machine):
        raise LiveError(f"cycle signal '{s.cycle_signal}' is none of the machine file's "
                        "signals (watch records only those)")
    for key, low, high in (("window_s", 1.0, 86_400.0), ("rotate_s", 60.0, 86_400.0),
                           ("publishing_ms", 10.0, 60_000.0)):
        v = getattr(s, key)
        if not low <= v <= high:
            raise LiveError(f"{key.replace('_s', '').replace('_ms', '')} {v:g} is outside "
                            f"{low:g}..{high:g}")
    if s.diagnose_every_s is not None and not 10.0 <= s.diagnose_every_s <= 86_400.0:
        raise LiveError(f"--diagnose-every {s.diagnose_every_s:g} s is outside 10 s..24 h")
    if s.gap_alarm_cycles < 1 or not s.gap_alarm_percent > 0:
        raise LiveError("--gap-alarm must be > 0 and --gap-cycles at least 1")
