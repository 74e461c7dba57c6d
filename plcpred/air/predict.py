"""The orchestration layer: machine file -> timeline -> demand profile -> files, in the
spirit of pvlib's ModelChain. Each stage is a plain function of the one before, so a
study can stop at any of them."""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

from ..errors import PlcpredError
from ..sequencer.timeline import NS, Timeline
from .demand import ConsumerModel, DemandProfile, consumer_models, demand_profile

DEFAULT_DT_S = 0.01
MAX_CELLS = 400_000          # keeps demand.csv to a few tens of MB
_NICE = (1, 2, 5)


def default_dt(horizon_s: float, max_cells: int = MAX_CELLS) -> float:
    """10 ms, or the smallest of 20/50/100/200/500 ms, 1/2/5/10 s ... that keeps the grid
    under ``max_cells`` cells."""
    dt = DEFAULT_DT_S
    if horizon_s / dt <= max_cells:
        return dt
    scale = 0.01
    while True:
        for k in _NICE:
            dt = k * scale
            if dt > DEFAULT_DT_S and horizon_s / dt <= max_cells:
                return dt
        scale *= 10


@dataclass
class Prediction:
    machine: object
    timeline: Timeline
    profile: DemandProfile
    models: list[ConsumerModel]
    stage_s: dict = field(default_factory=dict)
    write_files: list = field(default_factory=list)

    def summary(self) -> dict:
        data = self.profile.summary()
        data["machine"] = self.machine.name
        data["supply_bar_g"] = self.machine.supply_bar_g
        return data

    def write(self, out_dir, plot: bool = True) -> list[Path]:
        """``timeline.csv``, ``demand.csv``, ``summary.json`` and ``demand.png`` in
        ``out_dir`` (each through a temporary file)."""
        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        t0 = time.perf_counter()
        self.timeline.to_csv(out / "timeline.csv")
        self.profile.to_csv(out / "demand.csv")
        self.profile.write_summary(out / "summary.json", {
            "machine": self.machine.name, "supply_bar_g": self.machine.supply_bar_g})
        self.stage_s["write_csv"] = time.perf_counter() - t0
        files = [out / "timeline.csv", out / "demand.csv", out / "summary.json"]
        if plot:
            from ..report import plot_demand
            t0 = time.perf_counter()
            plot_demand(self.profile, out / "demand.png",
                        title=f"{self.machine.name}: air demand over "
                              f"{_span(self.profile.horizon_s)}")
            self.stage_s["plot"] = time.perf_counter() - t0
            files.append(out / "demand.png")
        self.write_files = files
        return files


def _span(seconds: float) -> str:
    if seconds >= 7200:
        return f"{seconds / 3600:g} h"
    if seconds >= 120:
        return f"{seconds / 60:g} min"
    return f"{seconds:g} s"


# demand grid cells x (consumers + 1) held at once: about 320 MB of float64
MAX_GRID_VALUES = 40_000_000


class GridError(PlcpredError, ValueError):
    """A demand grid that cannot be built (a step that is not positive, or too fine)."""


def predict(machine, horizon="60s", dt=None, program=None, timeline=None,
            max_events: int | None = None) -> Prediction:
    """Run ``machine`` (a path or a loaded machine) over ``horizon`` and turn its timeline
    into a demand profile on a ``dt`` grid (seconds, or a duration such as ``"1s"``;
    default :func:`default_dt`). ``max_events`` caps the signal changes held in memory
    (default: the sequencer's)."""
    from ..machine import Machine, load_machine
    from ..sequencer import parse_horizon, unfold

    stages = {}
    t0 = time.perf_counter()
    if not isinstance(machine, Machine):
        machine = load_machine(machine)
    if timeline is None:
        extra = {} if max_events is None else {"max_events": max_events}
        timeline = unfold(machine, horizon, program=program, **extra)
    stages["sequence"] = time.perf_counter() - t0
    horizon_s = timeline.horizon_ns / NS
    if dt is None:
        dt_s = default_dt(horizon_s)
    elif isinstance(dt, str):
        dt_s = parse_horizon(dt) / NS
    else:
        dt_s = float(dt)
    if not dt_s > 0:
        raise GridError("--dt must be positive")
    models = consumer_models(machine)
    values = (horizon_s / dt_s + 1) * (len(models) + 1)
    if values > MAX_GRID_VALUES:
        raise GridError(f"--dt {dt_s:g} s over {horizon_s:g} s gives {horizon_s / dt_s:,.0f} "
                        f"grid cells for {len(models)} consumers, more than the "
                        f"{MAX_GRID_VALUES:,} values plcpred holds; use a coarser --dt "
                        f"(at least {horizon_s * (len(models) + 1) / MAX_GRID_VALUES:.3g} s) "
                        "or leave it out for the default")
    t0 = time.perf_counter()
    profile = demand_profile(timeline, models, dt_s)
    stages["air_model"] = time.perf_counter() - t0
    return Prediction(machine, timeline, profile, models, stages)
