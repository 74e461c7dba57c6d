"""The command line's arguments, one function per command. Nothing here imports the
commands' code, so ``--help`` and argument errors answer at once."""
from __future__ import annotations

import argparse

from .. import __version__
from ..physics.units import P_ATM_KPA
from .args import (
    DT_HELP,
    HORIZON_HELP,
    consumers_arg,
    energy_args,
    json_arg,
    log_column_args,
    machine_args,
    max_rows_arg,
    positive_int,
    quiet_arg,
    seconds,
    seed,
    test_column_args,
    whole_number,
)


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(
        prog="plcpred",
        description="Predict the compressed-air demand of a machine from its PLC program.")
    ap.add_argument("--version", action="version", version=f"plcpred {__version__}")
    ap.add_argument("--debug", action="store_true",
                    help="show the Python traceback of an internal error (any position)")
    ap.add_argument("--allow-root", action="append", default=[], metavar="DIR",
                    help="also read programs, libraries and project files from under DIR "
                         "(repeatable, any position). By default only files under the "
                         "machine file's folder (or the project's) are read")
    sub = ap.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    _add_check(sub)
    _add_init(sub)
    _add_timeline(sub)
    _add_predict(sub)
    _add_size(sub)
    _add_compare(sub)
    _add_sweep(sub)
    _add_diagnose(sub)
    _add_emulate(sub)
    _add_identify(sub)
    _add_serve(sub)
    _add_watch(sub)
    return ap


def _add_check(sub) -> None:
    p = sub.add_parser("check", help="parse and validate PLC programs",
                       description="Parse and validate programs (.st, .seq, PLCopen .xml, "
                                   "TwinCAT .TcPOU/.TcGVL/.TcDUT/.TcIO/.TcTTO, or a whole "
                                   "TwinCAT project as a .plcproj or a folder). "
                                   "Files given together are checked as one project, so a "
                                   "global variable list can be checked with the POUs using "
                                   "it. Errors print as file:line:col: message; exit 1 if any.")
    p.add_argument("programs", nargs="+", metavar="PROGRAM")
    p.add_argument("--syntax-only", action="store_true",
                   help="skip semantic checks (for fragments using libraries not at hand)")
    p.add_argument("--allow-external", action="store_true",
                   help="names nothing at hand declares (types, FBs, functions, library "
                        "qualifiers) are warnings, not errors: for code that uses a library "
                        "you do not have. Such a project cannot run, so the compile check "
                        "is skipped")
    p.add_argument("--lib", action="append", default=[], metavar="PATH",
                   help="declarations of a library the programs use: an ST, TwinCAT or "
                        "PLCopen file, a .plcproj or a folder (repeatable; its name is "
                        "its namespace, as in Lib.FB_X). Stubs of common vendor libraries "
                        "are built in")
    p.add_argument("--dialect", choices=("auto", "iec", "bnr"), default="auto",
                   help="where vendors read ST differently: auto (default) tells a B&R "
                        "Automation Studio program by its files (.var/.typ/.fun, "
                        "PROGRAM _CYCLIC); bnr reads every file the B&R way (Act; calls an "
                        "action; a file of actions is read with its program folder); iec "
                        "never does")
    p.set_defaults(run=("check", "cmd_check"))


def _add_init(sub) -> None:
    p = sub.add_parser("init", help="write a machine file to start from, from a program's I/O",
                       description="Write a commented machine file for a program: its "
                                   "name, program and task interval filled in, every input "
                                   "as an [[input]] and every BOOL output as a [[consumer]] "
                                   "to uncomment and complete. The file loads as it is "
                                   "(the program alone, nothing scheduled). Without --out "
                                   "it is printed.")
    p.add_argument("program", metavar="PROGRAM",
                   help="the program (.st, .seq, PLCopen .xml, TwinCAT file, .plcproj or "
                        "folder)")
    p.add_argument("--out", "-o", metavar="MACHINE.toml",
                   help="write the machine file here (the program is named relative to it)")
    p.add_argument("--force", action="store_true", help="overwrite --out if it exists")
    p.set_defaults(run=("check", "cmd_init"))


def _add_timeline(sub) -> None:
    p = sub.add_parser("timeline", help="run a machine's program into output-bit timelines",
                       description="Run the machine's PLC program against its plant I/O "
                                   "model (cylinder end switches, input schedules) over a "
                                   "horizon and write DIR/timeline.csv: time_s,signal,value, "
                                   "one row per change, initial values at 0.")
    machine_args(p, dt=False)
    p.add_argument("--scan-stepping", action="store_true",
                   help="execute every scan instead of jumping between events (the slow "
                        "reference the event-driven mode must equal)")
    p.add_argument("--no-replay", action="store_true",
                   help="execute every part of a run that cannot tile instead of copying "
                        "the recorded response of a part that starts from a state the "
                        "machine rested in before (the result is the same, only slower)")
    max_rows_arg(p, "a longer timeline is an error, before anything is written")
    p.set_defaults(run=("predict", "cmd_timeline"))


def _add_predict(sub) -> None:
    p = sub.add_parser("predict", help="forecast a machine's compressed-air demand",
                       description="Run the machine's program (as `timeline` does) and turn "
                                   "its timeline into air demand: D1 volumes per cylinder "
                                   "stroke, D2 flows of nozzles while on and of leaks always. "
                                   "Writes DIR/timeline.csv, demand.csv (NL/min per consumer "
                                   "on a time grid), summary.json and demand.png, and prints "
                                   "a table of per-consumer totals.")
    machine_args(p)
    consumers_arg(p)
    p.add_argument("--no-plot", action="store_true", help="skip demand.png")
    p.add_argument("--no-timeline", action="store_true",
                   help="skip timeline.csv (the demand is computed all the same)")
    max_rows_arg(p, "a longer timeline is not written, with a warning")
    p.set_defaults(run=("predict", "cmd_predict"))


def _add_size(sub) -> None:
    p = sub.add_parser("size", help="size the compressor and receiver for a machine",
                       description="Predict the machine's demand over the horizon and size "
                                   "its supply: mean, peaks (instantaneous, 1 s, 1 min), 95th "
                                   "percentile, a compressor design flow (mean plus an "
                                   "allowance), the receiver that holds the pressure within a "
                                   "band, energy and cost per year, and the air used while "
                                   "idle. Writes DIR/sizing.json, sizing.md and sizing.html "
                                   "(self-contained, plots embedded).")
    machine_args(p)
    consumers_arg(p)
    p.add_argument("--allowance", default="10%",
                   help="design flow above the mean (default 10%%)")
    p.add_argument("--band", default="1bar",
                   help="pressure band the receiver must hold (default 1bar)")
    energy_args(p)
    p.add_argument("--idle-after", metavar="DURATION",
                   help="count air as idle only once no cylinder has moved for this long "
                        "(default: whenever no cylinder moves)")
    p.set_defaults(run=("predict", "cmd_size"))


def _add_compare(sub) -> None:
    p = sub.add_parser("compare", help="compare two machines or programs (CI gate)",
                       description="Predict BASE and NEW over the same horizon and print a "
                                   "per-consumer table of totals and deltas. Air is compared "
                                   "per cycle when both machines have one ([machine] "
                                   "cycle_signal, or a state that repeats), else over the "
                                   "horizon. Exit 0 when NEW "
                                   "is within the allowance, 1 when it uses more air, 2 on an "
                                   "error, 4 when NEW never moves (no valve output ever "
                                   "changes: a deadlock uses less air but passes no gate), 5 "
                                   "when NEW's cycles per hour drop by more than "
                                   "--max-throughput-drop (or it completes none). NEW "
                                   "defaults to BASE, for comparing two programs with "
                                   "--program-new.")
    p.add_argument("base", metavar="BASE", help="machine file (.toml)")
    p.add_argument("new", metavar="NEW", nargs="?", help="machine file (default: BASE)")
    p.add_argument("--horizon", required=True, help=HORIZON_HELP)
    p.add_argument("--max-increase", default="0%",
                   help="allowed increase: a percentage (2%%) or normal litres (0.5NL); "
                        "default 0%%; per cycle when the gate compares cycles")
    p.add_argument("--max-throughput-drop", default="5%", metavar="PCT",
                   help="allowed fall of NEW's cycles per hour against BASE's, a percentage; "
                        "default 5%%")
    p.add_argument("--program-base", metavar="PROGRAM", help="program to run on BASE")
    p.add_argument("--program-new", metavar="PROGRAM", help="program to run on NEW")
    p.add_argument("--dt", help=DT_HELP)
    json_arg(p, "the comparison")
    quiet_arg(p)
    p.set_defaults(run=("predict", "cmd_compare"))


def _add_sweep(sub) -> None:
    p = sub.add_parser("sweep", help="what-if study over combinations of settings",
                       description="Predict the machine for every combination of the --set "
                                   "values and print totals, mean, peak, cycles per hour, "
                                   "NL per cycle and energy per scenario, with the "
                                   "warnings size gives. KEY is a [machine] key (supply_bar_g, scan_ms, "
                                   "...), CONSUMER.FIELD (\"air knives.pressure_bar_g\", "
                                   "A.stroke_time_s with 0.2/0.3 for extend/retract), "
                                   "input.SIGNAL.FIELD, program.VAR for a variable's "
                                   "initial value as an ST literal (program.BLOW_TIME=T#2s), "
                                   "or measure.leaks / measure.pressure / measure.blowoff "
                                   "(saving measures, "
                                   "also as --measure). Energy and cost count a year as "
                                   "size does (--hours, the machine file's [calendar]). "
                                   "Scenarios run in parallel local processes, or on a Dask "
                                   "cluster with --engine dask --scheduler ADDRESS.")
    machine_args(p, out=None)
    p.add_argument("--set", action="append", default=[], metavar="KEY=V1,V2,...",
                   help="values to sweep (repeat for a cartesian product)")
    p.add_argument("--measure", action="append", default=[], metavar="NAME=VALUE",
                   help="an energy-saving measure, swept as without and with it: "
                        "leaks=-30%% (repair that share of every leak), pressure=-0.5bar "
                        "(lower the supply), blowoff=cycle (nozzles blow only while a "
                        "cycle runs, not while the machine waits); the same as --set "
                        "measure.NAME=AS_IS,VALUE")
    p.add_argument("--engine", choices=("local", "dask"), default="local")
    p.add_argument("--scheduler", metavar="ADDRESS", help="Dask scheduler (tcp://host:8786)")
    p.add_argument("--workers", type=int, help="local processes (default: one per core)")
    p.add_argument("--max-scenarios", type=positive_int, default=10_000, metavar="N",
                   help="most scenarios (the product of the --set value counts) a sweep "
                        "runs (default 10,000); more is an error before any work")
    p.add_argument("--out", metavar="DIR", help="also write DIR/sweep.csv")
    energy_args(p)
    p.set_defaults(run=("predict", "cmd_sweep"))


def _add_diagnose(sub) -> None:
    p = sub.add_parser("diagnose", help="diagnose the gap between prediction and a measured "
                                        "flow log",
                       description="Compare a machine's prediction with measured flow "
                                   "logs: baseline error, where in the cycle the gap lies "
                                   "(idle, a drive's strokes, a nozzle on, SFC steps), which "
                                   "unmodelled effect causes it (leak, passive_flow, "
                                   "supply_pressure, dead_volume, incomplete_exhaust, "
                                   "shared_supply, valve_delay, stroke_time, sensor_lag, "
                                   "meter_gain; none within the model's accuracy, or "
                                   "unexplained) and how far the gap shrinks with it on samples the "
                                   "fit never saw. Prints a report; exit 0 whatever the "
                                   "verdict, 2 on bad input.")
    p.add_argument("machine", metavar="MACHINE", help="machine file (.toml)")
    p.add_argument("--measured", action="append", required=True, metavar="RUN.csv",
                   help="a flow log: time_s,flow_l_min[,supply_bar_g] or any logger's CSV "
                        "(see --time-col/--flow-col); repeat for several runs")
    p.add_argument("--io", action="append", metavar="RUN.timeline.csv",
                   help="recorded I/O of each run (time_s,signal,value): valve edges from "
                        "the trace instead of the sequencer (one per --measured)")
    p.add_argument("--offset", action="append", type=seconds, metavar="S",
                   help="the logger's clock reading at the machine's start, per run "
                        "(default: found by correlating the log with the prediction)")
    p.add_argument("--max-offset", type=seconds, metavar="S",
                   help="search the clock offset within this many seconds of the log's "
                        "first sample (default: half the run, at most 120 s)")
    log_column_args(p)
    p.add_argument("--reference", choices=("iso8778", "din1343", "iso2533"),
                   help="the meter's reference condition (default: the machine file's "
                        "[meter] reference, else iso8778)")
    p.add_argument("--sampling", choices=("mean", "instant"),
                   help="what a reading is: the mean flow over its logging interval (a "
                        "meter's own logger) or the flow at that moment (a PLC polling the "
                        "meter's analogue output). Default: the machine file's [meter] "
                        "sampling, else mean (a warning says when the logs fit "
                        "instantaneous readings far better)")
    p.add_argument("--effects", metavar="A,B",
                   help="try only these effects (default: all that apply)")
    json_arg(p, "the diagnosis")
    p.add_argument("--out", metavar="DIR",
                   help="write diagnose.json, diagnose.png and diagnose.html to DIR")
    p.add_argument("--write-machine", metavar="FIXED.toml",
                   help="write the machine file with the diagnosed effect(s) added")
    p.add_argument("--program", metavar="PROGRAM",
                   help="run this program instead of the one the machine file names")
    p.add_argument("--no-plant", action="store_true",
                   help="do not run the machine through the physics plant as a second "
                        "reference (faster; the effects are then fitted in D1's terms "
                        "only)")
    quiet_arg(p)
    p.set_defaults(run=("diagnose", "cmd_diagnose"))


def _add_emulate(sub) -> None:
    p = sub.add_parser("emulate", help="run a machine in closed loop with the physics plant "
                                       "(a virtual flow meter log)",
                       description="Run the machine's program against the physics plant "
                                   "(chamber thermodynamics, ISO 6358 flows, valve delays, "
                                   "friction and load, supply lines, the flow meter) and "
                                   "write what a flow meter on it would log. --truth applies "
                                   "a partial machine file of the real machine's deviations "
                                   "(a hidden leak, a longer tube, a slow meter) that the "
                                   "prediction does not see. The physics plant integrates every "
                                   "stroke: horizons up to 24 h.")
    machine_args(p, "output directory (measured.csv, timeline.csv, plant.csv, "
                     "emulate.png)", dt=False)
    p.add_argument("--truth", metavar="T.toml",
                   help="the real machine's deviations from MACHINE (a partial machine file)")
    p.add_argument("--seed", type=seed, metavar="N", help="seed of the meter's noise (a "
                   "whole number >= 0)")
    p.add_argument("--no-plot", action="store_true", help="do not draw emulate.png")
    p.set_defaults(run=("emulate", "cmd_emulate"))


def _add_identify(sub) -> None:
    p = sub.add_parser("identify", help="ISO 6358 C, b, m (a) of a component from test data",
                       description="Identify the extended ISO 6358 parameters (C, b, m, a) "
                                   "of a valve, nozzle, circuit or leak from steady-flow "
                                   "points (p_up_bar_g, p_down_bar_g, flow_l_min) or a tank's "
                                   "pressure curve (time_s, p_bar_g with --volume-l). Prints "
                                   "them with 95 % confidence intervals.")
    p.add_argument("what", choices=("flow",), help="what to identify (flow)")
    p.add_argument("data", metavar="DATA.csv", help="the test data (CSV)")
    p.add_argument("--method", choices=("improved", "iso6358"), default="improved",
                   help="steady flow: improved (C from choked points, b and m by least "
                        "squares; default) or iso6358 (ISO 6358:1989, m = 0.5)")
    p.add_argument("--fit-a", action="store_true",
                   help="also fit the cracking pressure ratio a (check valves)")
    p.add_argument("--volume-l", type=float, metavar="L",
                   help="tank data: the tank's volume in litres")
    p.add_argument("--mode", choices=("discharge", "charge"), default="discharge",
                   help="tank data: emptying to atmosphere (default) or filling")
    p.add_argument("--supply-bar-g", type=float, metavar="P",
                   help="tank charge: the supply pressure (gauge)")
    test_column_args(p)
    p.add_argument("--atmosphere-kpa", type=float, default=P_ATM_KPA)
    p.add_argument("--temperature-c", type=float, default=20.0,
                   help="air temperature when the data have no t_up_c column")
    p.add_argument("--plot", metavar="FIT.png", help="write the fit plot")
    json_arg(p, "the result")
    p.add_argument("--machine", metavar="MACHINE.toml",
                   help="with --write-machine: the machine file to put the result into")
    p.add_argument("--consumer", metavar="NAME",
                   help="with --write-machine: the nozzle or leak that gets C, b, m, a")
    p.add_argument("--write-machine", metavar="OUT.toml",
                   help="write MACHINE with the identified C, b, m, a in CONSUMER")
    p.set_defaults(run=("identify", "cmd_identify"))


def _add_serve(sub) -> None:
    p = sub.add_parser("serve", help="serve the emulated machine over OPC UA (a digital twin)",
                       description="Run the machine's program against the physics plant (as "
                                   "emulate does) in real time, or --speed times as fast, and "
                                   "serve it as an OPC UA server: every signal of the machine "
                                   "file a Boolean node ns=2;s={signal}, the flow meter's "
                                   "reading ns=2;s=flow_l_min and the supply pressure "
                                   "ns=2;s=supply_bar_g, each value with its time on the "
                                   "machine's clock as the source time stamp. Stops when the "
                                   "horizon is served.")
    p.add_argument("machine", metavar="MACHINE", help="machine file (.toml)")
    p.add_argument("--endpoint", required=True, metavar="URL",
                   help="where to serve: opc.tcp://HOST:PORT")
    p.add_argument("--speed", type=float, default=1.0, metavar="N",
                   help="the machine's clock runs N times as fast as the wall clock "
                        "(default 1, at most 1000)")
    p.add_argument("--horizon", default="1h", metavar="H",
                   help="machine time to serve (default 1h, at most 24h)")
    p.add_argument("--truth", metavar="T.toml",
                   help="the real machine's deviations from MACHINE (a partial machine file, "
                        "as emulate --truth)")
    p.add_argument("--truth-at", metavar="T",
                   help="switch the --truth deviations on at machine time T (default: from "
                        "the start); they take over at the first moment from then on when "
                        "every signal agrees")
    p.add_argument("--epoch", metavar="TIME",
                   help="when the machine started (ISO 8601, UTC unless it says): a server "
                        "restarted with its first start's epoch goes on where the machine is "
                        "(default: now)")
    p.add_argument("--seed", type=seed, metavar="N", help="seed of the meter's noise")
    p.add_argument("--history", type=lambda t: whole_number(t, 0), default=0, metavar="N",
                   help="keep each node's last N values for HistoryRead: a watch that lost "
                        "its connection reads what it missed (default 0: none)")
    p.add_argument("--program", metavar="PROGRAM",
                   help="run this program instead of the one the machine file names")
    p.set_defaults(run=("live", "cmd_serve"))


def _add_watch(sub) -> None:
    p = sub.add_parser("watch", help="watch a running machine over OPC UA against the "
                                     "prediction",
                       description="Subscribe to the machine's signals and flow meter on an "
                                   "OPC UA server (the PLC's, a gateway's, or plcpred serve), "
                                   "record them in DIR as timeline-NNNN.csv and "
                                   "measured-NNNN.csv (as diagnose --io and --measured read "
                                   "them, a new pair every --rotate of machine time and after "
                                   "every gap) and compare each cycle's measured air with the "
                                   "air the model predicts from the recorded valve edges and "
                                   "with the reference learned from the first cycles: a "
                                   "line per cycle, events and alarms in DIR/events.jsonl. "
                                   "Node ids, the meter and the alarms come from the machine "
                                   "file's [live] table; the options below override it.")
    p.add_argument("machine", metavar="MACHINE", help="machine file (.toml)")
    p.add_argument("--endpoint", metavar="URL",
                   help="the OPC UA server, opc.tcp://HOST:PORT (default: [live] endpoint)")
    p.add_argument("--out", required=True, metavar="DIR", help="output directory")
    p.add_argument("--duration", metavar="D",
                   help="stop after D of wall-clock time (default: until Ctrl-C)")
    p.add_argument("--cycle-signal", metavar="SIGNAL",
                   help="compare between this signal's rising edges (default: [live] or "
                        "[machine] cycle_signal; without one, per --window)")
    p.add_argument("--window", metavar="T",
                   help="the comparison window without a cycle signal (default 60s)")
    p.add_argument("--rotate", metavar="T",
                   help="a new pair of files every T of machine time (default 1h)")
    p.add_argument("--gap-alarm", type=float, metavar="PERCENT",
                   help="alarm when a cycle's measured air departs from the reference "
                        "(see --learn-cycles) by more than this (default 10) ...")
    p.add_argument("--gap-cycles", type=positive_int, metavar="N",
                   help="... for N cycles in a row (default 3)")
    p.add_argument("--learn-cycles", type=lambda t: whole_number(t, 0), metavar="N",
                   help="judge the gap against a reference learned from the first N cycles "
                        "(D1 scaled per consumer to what the healthy machine measured; "
                        "default 10, 0: against D1 itself)")
    p.add_argument("--idle-limit", type=float, metavar="NL_MIN",
                   help="alarm when the flow while the machine rests exceeds this")
    p.add_argument("--publishing-ms", type=float, metavar="MS",
                   help="the subscription's publishing interval (default 100)")
    p.add_argument("--diagnose-every", metavar="T",
                   help="diagnose the last T of machine time (as plcpred diagnose does) every "
                        "T, in a worker process while recording goes on; the verdict is a "
                        "'diagnosis' event (e.g. 15min; at least 10s)")
    p.add_argument("--prometheus", metavar="[HOST:]PORT",
                   help="serve the comparison as Prometheus metrics at PORT (every "
                        "interface) or HOST:PORT; needs the prometheus-client package")
    p.add_argument("--plot", action="store_true", default=None,
                   help="draw DIR/comparison.png (measured against predicted per cycle, "
                        "the gap, alarms) when the watch ends (default: [live] plot)")
    p.set_defaults(run=("live", "cmd_watch"))
