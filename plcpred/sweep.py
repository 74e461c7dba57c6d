"""What-if sweeps: predictions over the cartesian product of settings, run in parallel
on local processes or on an existing Dask cluster.

A setting is ``KEY=V1,V2,...``:

* ``supply_bar_g``, ``scan_ms``, ``ambient_c``, ``atmosphere_kpa`` - the [machine] table;
* ``CONSUMER.FIELD`` - a consumer's field, e.g. ``air knives.pressure_bar_g``,
  ``A.stroke_time_s`` (one value for both directions or ``0.2/0.3``), ``knives.C``;
* ``input.SIGNAL.FIELD`` - an input schedule, e.g. ``input.PB1.period_s``;
* ``program.VAR`` - the initial value of a program variable or constant, as an ST literal,
  e.g. ``program.BLOW_TIME=T#2s,T#5s`` (a timer preset);
* ``measure.NAME`` - an energy-saving measure as audits (MEASUR, AIRMaster+) list them:
  ``measure.leaks=0%,-30%`` repairs that share of every leak (its conductance: a leak's
  flow is proportional to it, ISO 6358), ``measure.pressure=0,-0.5`` lowers the supply by
  that many bar (regulators set above the new supply then give the supply),
  ``measure.blowoff=always,cycle`` lets the nozzles blow only while a cycle is in progress
  (their valves closed while the machine waits, :func:`~plcpred.air.cycles.rest_spells_ns`).

Each scenario is a plain function call (:func:`run_scenario`) on picklable arguments, so
the local process pool and Dask give identical results.
"""
from __future__ import annotations

import copy
import itertools
import os
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass
from pathlib import Path

from .air import predict
from .air.cycles import blowing_only_in_cycle
from .air.sizing import DEFAULT_PRICE, size_prediction
from .errors import PlcpredError
from .machine import MachineError, machine_from_data, read_machine_data, schema
from .memory import use_large_malloc_thresholds
from .parser import ProgramError, parse_st
from .progress import Progress, progress_or_off

DASK_CONNECT_TIMEOUT_S = 10
# scenarios a sweep runs at most unless asked for more: every one is validated in this
# process first, and memory grows with their number (2x10^8 of them are 5.8 GB)
MAX_SCENARIOS = 10_000
# Dask settings for workers that run scenarios at the local pool's speed. A worker
# samples its running task's stack every 10 ms for its profile, and it, its nanny and
# the scheduler poll memory and system counters several times a second; a sweep keeps
# every core busy, so each of these takes its time from a scenario (bench/sweep_speed.py
# compares the local pool with Dask). Set them where the workers start (``dask.config.set``
# around a LocalCluster, or the DASK_DISTRIBUTED__... environment variables of
# ``dask worker``, docs/reference/cli.md); plcpred cannot change a running cluster's.
DASK_WORKER_CONFIG = {"distributed.worker.profile.enabled": False,
                      "distributed.worker.memory.monitor-interval": "1s",
                      "distributed.admin.system-monitor.interval": "2s"}
# what a sweep may vary: the machine file's numbers the air model reads (machine.schema)
MACHINE_KEYS = tuple(k for k, t in schema.key_types("machine").items() if t == "number")
_INPUT_NUMBERS = {k for k, t in schema.key_types("input").items() if t == "number"}
_CONSUMER_NUMBERS = {k for k, t in schema.key_types("consumer", plant=False).items()
                     if t == "number"}
_PAIR_FIELDS = {k for k, t in schema.key_types("consumer", plant=False).items()
                if t == "pair"}


class SweepError(PlcpredError, ValueError):
    pass


@dataclass
class Setting:
    key: str
    values: list[str]


def parse_setting(text: str) -> Setting:
    if "=" not in text:
        raise SweepError(f"--set {text!r}: write KEY=V1,V2,...")
    key, _, rest = text.partition("=")
    values = [v.strip() for v in rest.split(",") if v.strip()]
    if not key.strip() or not values:
        raise SweepError(f"--set {text!r}: write KEY=V1,V2,...")
    return Setting(key.strip(), values)


def scenarios(settings: list[Setting]) -> list[dict]:
    keys = [s.key for s in settings]
    return [dict(zip(keys, combo)) for combo in itertools.product(*(s.values for s in settings))]


def _number(key, text):
    try:
        return float(text)
    except ValueError:
        raise SweepError(f"{key}: {text!r} is not a number") from None


def apply_settings(data: dict, path, program, scenario: dict):
    """The machine (validated) and program IR with the scenario's settings applied.

    Settings change the machine file's TOML data, which then goes through the same
    loader and checks as a file (physical ranges included): a swept value the loader
    would reject in a file is rejected here too, naming the setting."""

    d = copy.deepcopy(data)
    prog = program
    for key, value in scenario.items():
        if key in MACHINE_KEYS:
            d.setdefault("machine", {})[key] = _number(key, value)
            continue
        if key.lower().startswith("measure."):
            _apply_measure(d, key, value)
            continue
        head, _, field = key.rpartition(".")
        if key.lower().startswith("program."):
            prog = _set_program_value(prog if prog is not program else copy.deepcopy(program),
                                      key.split(".", 1)[1], value, key)
            continue
        if head.lower().startswith("input."):
            sig = head.split(".", 1)[1]
            table = next((t for t in _tables(d, "input")
                          if str(t.get("signal", "")).upper() == sig.upper()), None)
            if table is None:
                raise SweepError(f"{key}: no [[input]] for signal '{sig}'")
            if field not in _INPUT_NUMBERS:
                raise SweepError(f"{key}: cannot sweep '{field}' of an input")
            table[field] = _number(key, value)
            continue
        table = next((t for t in _tables(d, "consumer") if t.get("name") == head), None)
        if table is None:
            names = ", ".join(str(t.get("name")) for t in _tables(d, "consumer"))
            raise SweepError(f"{key}: no consumer named '{head}' (consumers: {names})")
        if field in _PAIR_FIELDS:
            nums = [_number(key, p) for p in value.split("/")]
            table[field] = [nums[0], nums[-1]]
        elif field in _CONSUMER_NUMBERS:
            table[field] = _number(key, value)
            if field in ("orifice_mm", "Cd"):
                table.pop("C", None)
                table.setdefault("b", 0.528)
        elif field == "flow_model":
            table[field] = value
        else:
            raise SweepError(f"{key}: cannot sweep '{field}' of a consumer")
    try:
        machine = machine_from_data(d, path)
    except MachineError as e:
        shown = ", ".join(f"{k}={v}" for k, v in scenario.items())
        raise SweepError(f"scenario {shown}: {e}") from None
    return machine, prog


MEASURES = ("leaks", "pressure", "blowoff")
# measure.blowoff: the nozzles blow "always" (as the program says) or only "cycle" (not
# while the machine waits), applied to the run's timeline
BLOWOFF = ("always", "cycle")


def _apply_measure(d: dict, key: str, value: str) -> None:
    """A saving measure (module note) applied to the machine file's data."""
    name = key.split(".", 1)[1].lower()
    text = value.strip().lower()
    if name == "leaks":
        pct = _number(key, text.removesuffix("%"))
        if not -100.0 <= pct <= 0.0:
            raise SweepError(f"{key}: {value!r}: a leak repair is a share from 0% to -100%")
        factor = 1.0 + pct / 100.0
        consumers = _tables(d, "consumer")
        leaks = [t for t in consumers if t.get("kind") == "leak"]
        if not leaks:
            raise SweepError(f"{key}: the machine file has no leak consumer")
        if factor == 0.0:
            d["consumer"] = [t for t in consumers if t.get("kind") != "leak"]
            return
        for t in leaks:
            if "C" in t:
                t["C"] = _number(key, t["C"]) * factor
            elif "Cd" in t:
                t["Cd"] = _number(key, t["Cd"]) * factor
        return
    if name == "pressure":
        dp = _number(key, text.removesuffix("bar"))
        machine = d.setdefault("machine", {})
        supply = _number(key, machine.get("supply_bar_g", 6.0)) + dp
        machine["supply_bar_g"] = supply
        for t in _tables(d, "consumer"):
            if "pressure_bar_g" in t and _number(key, t["pressure_bar_g"]) > supply:
                t["pressure_bar_g"] = max(supply, 0.0)
        return
    if name == "blowoff":
        if text not in BLOWOFF:
            raise SweepError(f"{key}: {value!r}: blow-off is 'always' (as the program "
                             "switches it) or 'cycle' (not while the machine waits)")
        if not any(t.get("kind") == "nozzle" for t in _tables(d, "consumer")):
            raise SweepError(f"{key}: the machine file has no nozzle")
        return              # applied to the run (run_scenario)
    raise SweepError(f"{key}: no measure '{name}' (measures: {', '.join(MEASURES)})")


def measure_setting(text: str) -> Setting:
    """``--measure NAME=VALUE``: the machine as it is and with the measure."""
    if "=" not in text:
        raise SweepError(f"--measure {text!r}: write NAME=VALUE (leaks=-30%, "
                         "pressure=-0.5bar, blowoff=cycle)")
    name, _, value = text.partition("=")
    name, value = name.strip().lower(), value.strip()
    if name not in MEASURES or not value:
        raise SweepError(f"--measure {text!r}: measures are {', '.join(MEASURES)} "
                         "(leaks=-30%, pressure=-0.5bar, blowoff=cycle)")
    as_is = {"leaks": "0%", "pressure": "0bar", "blowoff": "always"}[name]
    return Setting(f"measure.{name}", [as_is, value])


def _blowoff(scenario: dict) -> str:
    for key, value in scenario.items():
        if key.lower() == "measure.blowoff":
            return str(value).strip().lower()
    return "always"


def _tables(data: dict, key: str) -> list:
    tables = data.get(key, [])
    return [t for t in tables if isinstance(t, dict)] if isinstance(tables, list) else []


def _set_program_value(program, name: str, value: str, key: str):
    try:
        snippet = parse_st(f"PROGRAM _P VAR _v : INT := {value}; END_VAR END_PROGRAM",
                           f"--set {key}")
    except ProgramError as e:
        raise SweepError(f"{key}: {value!r} is not an ST literal ({e.message})") from None
    literal = snippet.pous[0].var_blocks[0].decls[0].init
    found = False
    blocks = [g.block for g in program.globals]
    blocks += [b for c in program.configurations for b in c.var_blocks]
    blocks += [b for p in program.pous for b in p.var_blocks]
    for b in blocks:
        for d in b.decls:
            if d.name.upper() == name.upper():
                d.init = literal
                found = True
    if not found:
        raise SweepError(f"{key}: the program declares no variable '{name}'")
    return program


def run_scenario(machine_path: str, scenario: dict, horizon_s: float, dt_s,
                 program_path: str | None = None, hours: float | None = None,
                 sec: float | None = None, price: float | None = None,
                 compressor=None) -> dict:
    """One prediction with the scenario applied: a row of totals, the cycle (per hour
    and NL per cycle; None without a steady cycle), the year's air, energy and cost
    (``hours`` None: the machine file's [calendar], else 4000 h), and under
    ``warnings`` what ``size`` would warn of (a machine that stands still before the
    horizon ends)."""

    data = read_machine_data(machine_path)
    base = machine_from_data(data, machine_path)
    program = _program_of(base, program_path)
    machine, program = apply_settings(data, machine_path, program, scenario)
    result = predict(machine, horizon_s, dt=dt_s, program=program)
    if _blowoff(scenario) == "cycle":
        result = predict(machine, horizon_s, dt=dt_s, program=program,
                         timeline=blowing_only_in_cycle(machine, result.timeline))
    s = size_prediction(result, hours, sec_kwh_per_nm3=sec, compressor=compressor,
                        price_per_kwh=DEFAULT_PRICE if price is None else price)
    row = dict(scenario)
    row.update({"total_nl": s.total_nl, "mean_l_min": s.mean_l_min,
                "peak_l_min": s.peak_l_min, "peak_1s_l_min": s.peak_1s_l_min,
                "cycles_per_hour": s.cycles_per_hour, "nl_per_cycle": s.nl_per_cycle,
                "air_nm3_per_year": s.air_nm3_per_year,
                "energy_kwh_per_year": s.energy_kwh_per_year,
                "cost_per_year": s.cost_per_year})
    for name, v in zip(result.profile.names, result.profile.consumer_nl):
        row[f"{name}_nl"] = float(v)
    row["warnings"] = list(s.warnings)
    return row


_PROGRAMS: dict = {}       # per process: the state of a program's files -> its IR
MAX_CACHED_PROGRAMS = 4


def _program_of(base, program_path: str | None):
    """``base``'s program, parsed once per process while its files stay as they are (a
    sweep's scenarios share it: parsing was a quarter of a pick-and-place scenario). The
    IR is shared read-only: settings that change it work on a copy (apply_settings)."""
    path = Path(base.program_path if program_path is None else program_path)
    key = (str(path.resolve()), _files_state(path),
           tuple((str(p), _files_state(Path(p))) for p in base.library_paths))
    if not path.is_dir() and path.suffix.lower() not in (".st", ".seq", ".xml", ".txt"):
        key += (_files_state(path.parent),)     # a project file names files beside it
    program = _PROGRAMS.get(key)
    if program is None:
        program = base.read_program(program_path)
        if len(_PROGRAMS) >= MAX_CACHED_PROGRAMS:
            _PROGRAMS.pop(next(iter(_PROGRAMS)))
        _PROGRAMS[key] = program
    return program


def _files_state(path: Path) -> tuple:
    """(name, size, modification time) of a file, or of every file under a folder."""
    try:
        if path.is_dir():
            return tuple((str(f.relative_to(path)), f.stat().st_size, f.stat().st_mtime_ns)
                         for f in sorted(path.rglob("*")) if f.is_file())
        st = path.stat()
        return (st.st_size, st.st_mtime_ns)
    except OSError:
        return ("unreadable",)


def sweep(machine_path, settings: list[Setting], horizon_s: float, dt_s=None,
          engine: str = "local", scheduler: str | None = None, workers: int | None = None,
          progress: Progress | bool | None = None, program=None, hours: float | None = None,
          sec: float | None = None, price: float | None = None,
          compressor=None, max_scenarios: int = MAX_SCENARIOS,
          notes: list | None = None) -> list[dict]:
    """Rows of :func:`run_scenario` for every scenario, in scenario order. More than
    ``max_scenarios`` is an error before any work; ``notes`` hears of what the user
    should know about the run (a Dask worker lost on the way); ``progress`` shows the
    scenarios done (:func:`~plcpred.progress.progress_or_off`)."""
    progress = progress_or_off(progress)
    count = 1
    for s in settings:
        count *= len(s.values)
    if count > max_scenarios:
        sizes = " x ".join(str(len(s.values)) for s in settings)
        raise SweepError(f"{count:,} scenarios ({sizes}) is more than --max-scenarios "
                         f"{max_scenarios:,}; sweep fewer values or raise the limit")
    if engine == "dask":
        # workers may start in another folder: they read the files by absolute path
        machine_path = Path(machine_path).resolve()
        if program is not None:
            program = Path(program).resolve()
    machine_path = str(machine_path)
    combos = scenarios(settings)
    progress.stage(f"checking {len(combos):,} scenarios")
    # fail fast, in this process, on settings that cannot apply
    data = read_machine_data(machine_path)
    base = machine_from_data(data, machine_path)
    program_path = str(program) if program is not None else None
    prog = base.read_program(program_path)
    for sc in combos:
        apply_settings(data, machine_path, prog, sc)
    args = [(machine_path, sc, horizon_s, dt_s, program_path, hours, sec, price, compressor)
            for sc in combos]
    if engine not in ("local", "dask"):
        raise SweepError(f"unknown engine '{engine}' (local or dask)")
    with progress.bar(len(combos), "scenarios") as bar:
        if engine == "dask":
            return _run_dask(args, scheduler, bar, notes if notes is not None else [])
        return _run_local(args, workers, bar)


def _run_local(args, workers: int | None, bar) -> list[dict]:
    """The scenarios of ``args`` in this process (one worker) or a pool of processes."""
    workers = workers or min(len(args), os.cpu_count() or 1)
    if workers <= 1:
        rows = []
        for a in args:
            rows.append(run_scenario(*a))
            bar.update()
        return rows
    rows = [None] * len(args)
    with ProcessPoolExecutor(max_workers=workers,
                             initializer=use_large_malloc_thresholds) as pool:
        futures = {pool.submit(run_scenario, *a): k for k, a in enumerate(args)}
        for f in as_completed(futures):
            rows[futures[f]] = f.result()
            bar.update()
    return rows


def run_batch(batch: list) -> list[dict]:
    """:func:`run_scenario` for each argument tuple of ``batch``: one Dask task (its
    worker's allocator set as plcpred's own processes have it, see
    :mod:`plcpred.memory`: the nanny's MALLOC_TRIM_THRESHOLD_ would make it 1.6x slower)."""
    use_large_malloc_thresholds()
    return [run_scenario(*a) for a in batch]


def guided_batches(n: int, threads: int, per_thread: int = 2) -> list[list[int]]:
    """Scenario indices 0..n-1 in batches of falling size (guided self-scheduling): each
    batch a ``per_thread * threads``-th of what is left. Every batch costs the
    scheduler, the client and the worker some CPU, taken from the scenarios when a sweep
    keeps every core busy, so the first batches are large; the last ones hold one
    scenario each, so no worker is left with a long batch while the others idle at the
    end. Rows stream back as batches finish. Measured on two cores (64 scenarios, five
    interleaved rounds, Dask over local): 1.035x with a quarter per thread of what is
    left, 0.995x with half, 1.087x with an eighth."""
    out, start = [], 0
    while start < n:
        size = max(1, (n - start) // (per_thread * max(1, threads)))
        out.append(list(range(start, min(n, start + size))))
        start += size
    return out


def _run_dask(args, scheduler, bar, notes: list):
    try:
        # dask is optional (the dask extra): only --engine dask needs it
        from dask.distributed import Client, as_completed
    except ImportError:
        raise SweepError("--engine dask needs dask.distributed: pip install "
                         "'plcpred[dask]'") from None
    if not scheduler:
        raise SweepError("--engine dask needs --scheduler ADDRESS (tcp://host:8786) of a "
                         "running Dask cluster")
    if hasattr(scheduler, "submit"):
        client = scheduler
    else:
        try:
            client = Client(scheduler, timeout=DASK_CONNECT_TIMEOUT_S)
        except (OSError, TimeoutError, ValueError, TypeError) as e:
            raise SweepError(f"--scheduler {scheduler}: no Dask scheduler answered within "
                             f"{DASK_CONNECT_TIMEOUT_S} s ({type(e).__name__}: "
                             f"{str(e).splitlines()[0][:120] if str(e) else 'no detail'}); "
                             "is the cluster running and the address right "
                             "(tcp://host:8786)?") from None
    try:
        workers = set(client.nthreads())
        threads = max(1, sum(client.nthreads().values()))
        batches = guided_batches(len(args), threads)
        futures = [client.submit(run_batch, [args[k] for k in b], pure=False)
                   for b in batches]
        index = {f.key: b for f, b in zip(futures, batches)}
        rows = [None] * len(args)
        for f in as_completed(futures):
            for k, row in zip(index[f.key], f.result()):
                rows[k] = row
                bar.update()
        lost = sorted(workers - set(client.nthreads()))
        if lost:
            notes.append(f"{len(lost)} Dask worker(s) left during the sweep "
                         f"({', '.join(lost[:3])}{', ...' if len(lost) > 3 else ''}); "
                         "the scheduler ran their scenarios again on the others, so every "
                         "row is complete")
        return rows
    finally:
        if client is not scheduler:
            client.close()
