"""The orchestration layer: machine file -> timeline -> demand profile -> files, in the
spirit of pvlib's ModelChain. Each stage is a plain function of the one before, so a
study can stop at any of them."""
from __future__ import annotations

import time
from dataclasses import dataclass, field

from ..errors import PlcpredError
from ..machine import as_machine
from ..sequencer import parse_horizon, unfold
from ..sequencer.timeline import NS, Timeline
from .demand import (
    SHOWN_CONSUMERS,
    ConsumerModel,
    DemandProfile,
    consumer_models,
    demand_profile,
    shows_every_consumer,
)

DEFAULT_DT_S = 0.01
MAX_CELLS = 400_000          # rows of demand.csv
MAX_CSV_VALUES = 6_000_000   # rows x columns: keeps demand.csv to a few tens of MB
_NICE = (1, 2, 5)


def csv_columns(n_consumers: int, shown: int | None = SHOWN_CONSUMERS) -> int:
    """Columns of ``demand.csv`` for a machine of ``n_consumers``: time, total, and each
    consumer, or the ``shown`` largest and "other" (:meth:`DemandProfile.groups`)."""
    if shows_every_consumer(n_consumers, shown):
        return 2 + n_consumers
    return 3 + shown


def default_dt(horizon_s: float, max_cells: int = MAX_CELLS, columns: int = 0) -> float:
    """10 ms, or the smallest of 20/50/100/200/500 ms, 1/2/5/10 s ... that keeps the grid
    under ``max_cells`` cells and, with ``columns``, ``demand.csv`` under MAX_CSV_VALUES
    values (a wide machine written in full gets a coarser grid)."""
    if columns:
        max_cells = max(1, min(max_cells, MAX_CSV_VALUES // columns))
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
    shown: int | None = SHOWN_CONSUMERS       # consumers shown one by one in the outputs

    def summary(self) -> dict:
        data = self.profile.summary()
        data["machine"] = self.machine.name
        data["supply_bar_g"] = self.machine.supply_bar_g
        return data


# grid cells held at once (the total, its cumulative sum, a few copies): 160 MB each
MAX_GRID_CELLS = 20_000_000


class GridError(PlcpredError, ValueError):
    """A demand grid that cannot be built (a step that is not positive, or too fine)."""


def predict(machine, horizon="60s", dt=None, program=None, timeline=None,
            max_events: int | None = None, shown: int | None = SHOWN_CONSUMERS
            ) -> Prediction:
    """Run ``machine`` (a path or a loaded machine) over ``horizon`` and turn its timeline
    into a demand profile on a ``dt`` grid (seconds, or a duration such as ``"1s"``;
    default :func:`default_dt` for the columns ``demand.csv`` will have). ``max_events``
    caps the signal changes held in memory (default: the sequencer's); ``shown`` is how
    many consumers the files show one by one before "other" (None: all)."""

    stages = {}
    t0 = time.perf_counter()
    machine = as_machine(machine)
    if timeline is None:
        extra = {} if max_events is None else {"max_events": max_events}
        timeline = unfold(machine, horizon, program=program, **extra)
    stages["sequence"] = time.perf_counter() - t0
    horizon_s = timeline.horizon_ns / NS
    models = consumer_models(machine)
    if dt is None:
        dt_s = default_dt(horizon_s, columns=csv_columns(len(models), shown))
    elif isinstance(dt, str):
        dt_s = parse_horizon(dt) / NS
    else:
        dt_s = float(dt)
    if not dt_s > 0:
        raise GridError("--dt must be positive")
    if horizon_s / dt_s > MAX_GRID_CELLS:
        raise GridError(f"--dt {dt_s:g} s over {horizon_s:g} s gives {horizon_s / dt_s:,.0f} "
                        f"grid cells, more than the {MAX_GRID_CELLS:,} plcpred holds; use a "
                        f"coarser --dt (at least {horizon_s / MAX_GRID_CELLS:.3g} s) or leave "
                        "it out for the default")
    t0 = time.perf_counter()
    profile = demand_profile(timeline, models, dt_s)
    stages["air_model"] = time.perf_counter() - t0
    return Prediction(machine, timeline, profile, models, stages, shown=shown)
