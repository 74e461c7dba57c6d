"""Argument types and option groups shared by several commands: each type turns one
command-line word into a value or an argparse error that says what was expected."""
from __future__ import annotations

import argparse
import re

from ..output import SHOWN_CONSUMERS
from ..physics.units import CFM_M3_MIN


def shown_consumers(text: str) -> int | None:
    """``--consumers``: a number of consumers, or ``all``."""
    if text.strip().lower() == "all":
        return None
    try:
        n = int(text)
    except ValueError:
        n = 0
    if n < 1:
        raise argparse.ArgumentTypeError(f"expected a whole number >= 1 or 'all', not {text!r}")
    return n


def consumers_arg(p) -> None:

    p.add_argument("--consumers", type=shown_consumers, default=SHOWN_CONSUMERS,
                   metavar="N|all",
                   help="consumers shown one by one in demand.csv and demand.png: the N "
                        "largest users and 'other' for the rest when the machine has more "
                        f"than N+1 (default {SHOWN_CONSUMERS}); 'all' for every one (the "
                        "default grid then coarsens to keep demand.csv to a few million "
                        "values)")


def fraction(text: str, option: str = "--allowance") -> float:
    """``10%`` or ``0.1``."""
    t = text.strip()
    try:
        return float(t[:-1]) / 100 if t.endswith("%") else float(t)
    except ValueError:
        raise ValueError(f"{option}: cannot read {text!r}: write e.g. 10% or 0.1") from None


def bar(text: str, option: str = "--band") -> float:
    t = text.strip().lower()
    try:
        if t.endswith("kpa"):
            return float(t[:-3]) / 100
        return float(t[:-3]) if t.endswith("bar") else float(t)
    except ValueError:
        raise ValueError(f"{option}: cannot read {text!r}: write e.g. 1bar, 0.5 or "
                         "50kPa") from None


def currency(text: str) -> str:
    """A currency as reports show it: short printable text (EUR, USD, CHF, ...)."""
    t = text.strip()
    if t and (len(t) > 8 or not t.replace(" ", "").isalnum()):
        raise argparse.ArgumentTypeError(f"a currency is a short code such as EUR, not "
                                         f"{text!r}")
    return t


def percentage(text: str, option: str) -> float:
    """``"5%"`` or ``"5"`` -> 5.0, from 0 to 100."""
    try:
        value = float(text.strip().rstrip("%"))
    except ValueError:
        raise ValueError(f"{option} takes a percentage such as 5%, not {text!r}") from None
    if not 0.0 <= value <= 100.0:
        raise ValueError(f"{option} takes a percentage from 0 to 100, not {text!r}")
    return value


HORIZON_HELP = "how long to run: 60s, 1m30s, 8h, T#1m30s (m = minutes)"


DT_HELP = ("grid step of the demand (default 10ms, coarser for long horizons so files stay "
           "under a few tens of MB)")


def max_rows_arg(p, beyond: str) -> None:
    p.add_argument("--max-rows", type=positive_int, default=DEFAULT_MAX_ROWS, metavar="N",
                   help=f"most rows of timeline.csv (default {DEFAULT_MAX_ROWS:,}, about "
                        f"{DEFAULT_MAX_ROWS * 30 / 1e9:.1f} GB); {beyond}")


def machine_args(p, out: str | None = "output directory", dt: bool = True) -> None:
    """The arguments every machine-running command shares."""
    p.add_argument("machine", metavar="MACHINE", help="machine file (.toml)")
    p.add_argument("--horizon", required=True, help=HORIZON_HELP)
    if out:
        p.add_argument("--out", required=True, metavar="DIR", help=out)
    if dt:
        p.add_argument("--dt", help=DT_HELP)
    p.add_argument("--program", metavar="PROGRAM",
                   help="run this program instead of the one the machine file names")
    if out:
        p.add_argument("--max-events", type=positive_int, default=DEFAULT_MAX_CHANGES,
                       metavar="N", help="most signal changes held in memory (default "
                       f"{DEFAULT_MAX_CHANGES:,}); a program that changes a signal every "
                       "scan over a long horizon stops with an error naming it")


DEFAULT_MAX_CHANGES = 20_000_000  # the sequencer's default (not imported: --help stays fast)


# timeline.csv rows written at most unless --max-rows says otherwise (about 30 bytes a
# row: 1.5 GB); a tiled year of a fast machine would otherwise fill the disk
DEFAULT_MAX_ROWS = 50_000_000


EXIT_NEVER_MOVES = 4   # compare: NEW never moves (a deadlock passes no air gate)


EXIT_THROUGHPUT_DROP = 5   # compare: NEW completes fewer cycles per hour than allowed


def whole_number(text: str, least: int) -> int:
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, not {text!r}") from None
    if n < least:
        raise argparse.ArgumentTypeError(f"must be at least {least}" if least else
                                         "must be 0 or more")
    return n


def seed(text: str) -> int:
    return whole_number(text, 0)


def positive_int(text: str) -> int:
    return whole_number(text, 1)


def energy_args(p) -> None:
    """How a year's energy and cost are counted (size and sweep)."""
    p.add_argument("--hours", type=nonneg_float, default=None,
                   help="production hours per year (default: the machine file's "
                        "[calendar], else 4000)")
    p.add_argument("--sec", type=nonneg_float, default=None,
                   help="specific energy, kWh per normal m^3 (default: isothermal "
                        "compression to the supply pressure over 57.4 %% efficiency, "
                        "0.1 at 7 bar gauge)")
    p.add_argument("--compressor-power", type=specific_power, default=None,
                   metavar="POWER",
                   help="the compressor's specific package input power at full load, from "
                        "its data sheet: 16.5kW/100cfm (CAGI) or 5.8kW/(m3/min) (ISO "
                        "1217); the specific energy then follows the supply pressure with "
                        "this compressor's efficiency (instead of 57.4 %%)")
    p.add_argument("--compressor-bar", type=nonneg_float, default=7.0, metavar="BAR_G",
                   help="the full-load pressure the data sheet rates it at, bar gauge "
                        "(default 7; 100 psig is 6.9)")
    p.add_argument("--price", type=nonneg_float, default=0.15,
                   help="energy price per kWh (default 0.15)")
    p.add_argument("--currency", default="", type=currency,
                   help="what --price and the cost are in, shown with them (EUR, USD, ...)")


# a data sheet's units of specific power: per 100 cfm (CAGI) or per m^3/min (ISO 1217)
_POWER_UNITS = {"kw/100cfm": "100cfm", "kw/(m3/min)": "m3/min", "kw/m3/min": "m3/min",
                "kw/(m³/min)": "m3/min", "kw/m³/min": "m3/min"}


def specific_power(text: str) -> float:
    """A data sheet's specific power as kW per m^3/min: '16.5kW/100cfm', '5.8kW/(m3/min)'."""

    m = re.fullmatch(r"\s*([0-9.]+(?:[eE][-+]?\d+)?)\s*(\S+)\s*", text)
    unit = _POWER_UNITS.get(m.group(2).lower()) if m else None
    if unit is None:
        raise argparse.ArgumentTypeError(
            f"expected a specific power such as 16.5kW/100cfm or 5.8kW/(m3/min), not {text!r}")
    value = float(m.group(1)) / (100.0 * CFM_M3_MIN if unit == "100cfm" else 1.0)
    if not 0 < value < float("inf"):
        raise argparse.ArgumentTypeError("a specific power must be > 0")
    return value


def nonneg_float(text: str) -> float:
    try:
        x = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, not {text!r}") from None
    if not x >= 0 or x == float("inf"):
        raise argparse.ArgumentTypeError("must be a finite number >= 0")
    return x


def seconds(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected seconds, not {text!r}") from None
    if v != v or abs(v) > 1e12:
        raise argparse.ArgumentTypeError(f"expected a finite number of seconds, not {text!r}")
    return v
