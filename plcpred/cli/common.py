"""What the commands share while they run: the horizon and output folder, exit codes for
errors, warnings about cut strokes, the compressor's data sheet."""
from __future__ import annotations

import sys

from ..air.sizing import CompressorSheet
from ..errors import EXIT_BAD_INPUT, PlcpredError
from ..output import check_out_dir
from ..sequencer import parse_horizon


def durations(args) -> tuple[float, float | None]:
    """(horizon in s, grid step in s or None) from --horizon and --dt."""

    horizon_s = parse_horizon(args.horizon) / 1e9
    dt = getattr(args, "dt", None)
    if not dt:
        return horizon_s, None
    try:
        return horizon_s, parse_horizon(dt) / 1e9
    except ValueError:
        raise ValueError(f"--dt: cannot read {dt!r}: write e.g. 10ms, 0.5s or 1s") from None


class UsageError(PlcpredError):
    """A bad option value: ``main`` prints it as ``plcpred: error: ...`` and exits 2."""


def horizon_and_out(args):
    """(horizon in s, grid step in s or None, the checked output directory) of a command
    that runs a machine into DIR; bad values raise (exit 2 through ``main``)."""

    try:
        horizon_s, dt_s = durations(args)
    except ValueError as e:
        raise UsageError(str(e)) from None
    return horizon_s, dt_s, check_out_dir(args.out)


def command_line(args) -> str:
    """What the manifest records as the command that wrote a directory."""
    return " ".join(["plcpred"] + [str(a) for a in getattr(args, "argv", [])])


def exit_code(e: PlcpredError) -> int:
    """The exit code of a command stopped by ``e``: 2, whatever was wrong with what the
    user gave (a machine file, a program that does not compile or cannot run, a path, a
    horizon). CI reads 1 as "the gate failed", which only ``compare`` and ``check`` say
    (plcpred.errors.EXIT_CODES)."""
    return EXIT_BAD_INPUT


def fail(message: str) -> int:
    print(f"plcpred: error: {message}", file=sys.stderr)
    return EXIT_BAD_INPUT


def too_many_rows(rows: int, limit: int) -> str:
    size_mb = rows * 30 / 1e6          # about 30 bytes a row
    size = f"{size_mb / 1e3:.1f} GB" if size_mb >= 1e3 else f"{size_mb:.0f} MB"
    return f"timeline.csv would hold {rows:,} rows (about {size}), more than --max-rows {limit:,}"


def cut_stroke_warnings(machine, profile) -> list[str]:
    """Drives whose valve reverses before they arrive, booked in full by D1."""
    out = []
    for name, n in profile.cut_strokes.items():
        if n and not machine.consumer(name).partial_strokes:
            total = sum(profile.strokes.get(name, (0, 0)))
            out.append(f'consumer "{name}": {n} of its {total} strokes are cut short by the '
                       "next edge (the valve reverses before the drive arrives, as a short "
                       "pulse or a chattering valve does); D1 books each in full. "
                       "partial_strokes = true (with exhaust_tau_s) counts the share the "
                       "piston covers (docs/reference/physics.md)")
    return out


def compressor(args):
    """The data sheet of --compressor-power/--compressor-bar (None without them)."""

    if args.compressor_power is None:
        return None
    if args.sec is not None:
        raise ValueError("give --sec or --compressor-power, not both: --sec is the specific "
                         "energy itself")
    return CompressorSheet(args.compressor_power, args.compressor_bar)
