"""Argument types and option groups shared by several commands: each type turns one
command-line word into a value or an argparse error that says what was expected."""
from __future__ import annotations

import argparse
import math
import re

from ..datafile import FLOW_UNIT_SPELLINGS, PRESSURE_UNIT_SPELLINGS, unit_name
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


def _unit_type(spellings: dict, what: str):
    def unit(text: str) -> str:
        name = unit_name(text, spellings)
        if name is None:
            raise argparse.ArgumentTypeError(f"unknown {what} unit {text!r} (known: "
                                             f"{', '.join(spellings)})")
        return name
    unit.__name__ = f"{what} unit"
    return unit


flow_unit = _unit_type(FLOW_UNIT_SPELLINGS, "flow")
pressure_unit = _unit_type(PRESSURE_UNIT_SPELLINGS, "pressure")

FLOW_UNIT_HELP = (f"{', '.join(FLOW_UNIT_SPELLINGS)} (at the meter's reference condition; "
                  "also as headers spell them: NL/min, lpm, slpm, Nm3/h, Nm³/h, m3/min, "
                  "cfm, ...)")
PRESSURE_UNIT_HELP = (f"{', '.join(PRESSURE_UNIT_SPELLINGS)} (gauge; bara, psia, kpaa "
                      "absolute; also as headers spell them: bar(g), psig, kPa, ...)")


def log_column_args(p, supply: bool = True) -> None:
    """Where a logger's CSV holds its values and in which units (diagnose, identify)."""
    p.add_argument("--time-col", metavar="NAME|N", help="time column (default time_s, else "
                   "the one column named as a time: Time, Timestamp, Zeit, Uhrzeit, ...; a "
                   "name such as t_ms or 'Zeit [ms]' gives numbers in ms, '(min)' in "
                   "minutes); seconds, ISO 8601 date-times, a logger's date-times "
                   "(24.11.2026 13:05:00,5; 2026/11/24 13:05:00; 11/24/2026 1:05:00 PM) or "
                   "times of day (13:05:00.5). Lines above the header (device, serial) are "
                   "skipped")
    p.add_argument("--date-col", metavar="NAME|N",
                   help="date column, for a time column that holds the time of day only "
                        "(default: the one column named as a date, Date or Datum, beside a "
                        "time column named Time, Zeit or Uhrzeit)")
    p.add_argument("--flow-col", metavar="NAME|N",
                   help="flow column (default flow_l_min, else the one column named as a "
                        "flow: Flow, Durchfluss, Volumenstrom, FAD, Debit, ...)")
    p.add_argument("--flow-unit", type=flow_unit, metavar="UNIT",
                   help="unit of the flow column: " + FLOW_UNIT_HELP + ". Default: the unit "
                        "its header names, as in 'Flow (m3/h)' (a warning where --flow-unit "
                        "says another), else l/min")
    if supply:
        p.add_argument("--supply-col", metavar="NAME|N",
                       help="supply pressure column (default supply_bar_g, else the one "
                            "column named as a pressure: Pressure, Druck, ...): its readings "
                            "bound the supply the diagnosis may find")
        p.add_argument("--supply-unit", type=pressure_unit, metavar="UNIT",
                       help="unit of the supply column: " + PRESSURE_UNIT_HELP + ". "
                            "Default: the unit its header names, as in 'Druck [psi]', else "
                            "bar(g)")


def test_column_args(p) -> None:
    """Where test data hold their values (identify), named as diagnose names a log's."""
    p.add_argument("--time-col", metavar="NAME|N",
                   help="tank data: the time column, seconds (default time_s)")
    p.add_argument("--flow-col", metavar="NAME|N",
                   help="steady flow: the flow column (default flow_l_min)")
    p.add_argument("--flow-unit", type=flow_unit, metavar="UNIT",
                   help="unit of --flow-col: " + FLOW_UNIT_HELP + ". Default: the unit its "
                        "header names, as in 'Q [m3/h]', else l/min")
    p.add_argument("--p-up-col", metavar="NAME|N",
                   help="steady flow: the upstream pressure column (default p_up_bar_g, "
                        "p_up_bar or p_up_kpa)")
    p.add_argument("--p-down-col", metavar="NAME|N",
                   help="steady flow: the downstream pressure column (default p_down_bar_g, "
                        "p_down_bar or p_down_kpa; without one, atmospheric)")
    p.add_argument("--pressure-col", metavar="NAME|N",
                   help="tank data: the tank's pressure column (default p_bar_g, p_bar or "
                        "p_kpa)")
    p.add_argument("--pressure-unit", type=pressure_unit, metavar="UNIT",
                   help="unit of the pressure columns named above: " + PRESSURE_UNIT_HELP
                        + ". Default: the unit each header names, as in 'p1 [psi]', else "
                        "bar(g)")


def json_arg(p, what: str) -> None:
    """``--json PATH``, the same on every command: ``-`` is stdout, which then holds the
    JSON alone (what the command prints otherwise goes to stderr)."""
    p.add_argument("--json", metavar="PATH",
                   help=f"also write {what} as JSON to PATH; - for stdout, which then "
                        "holds the JSON alone (the text goes to stderr)")


def quiet_arg(p) -> None:
    p.add_argument("--quiet", "-q", action="store_true",
                   help="show no progress on stderr (it is shown only while stderr is a "
                        "terminal; warnings and errors are printed all the same)")


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
    quiet_arg(p)


DEFAULT_MAX_CHANGES = 20_000_000  # the sequencer's default (not imported: --help stays fast)


# timeline.csv rows written at most unless --max-rows says otherwise (about 30 bytes a
# row: 1.5 GB); a tiled year of a fast machine would otherwise fill the disk
DEFAULT_MAX_ROWS = 50_000_000


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
    if math.isnan(v) or abs(v) > 1e12:
        raise argparse.ArgumentTypeError(f"expected a finite number of seconds, not {text!r}")
    return v
