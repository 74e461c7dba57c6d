"""A blind benchmark of ``plcpred diagnose`` (semi-synthetic tier).

Each case takes a sample machine, withholds one effect of random size from it, and makes
measured runs of the machine *with* the effect through a random flow meter (response
0.1-0.6 s, logging 1-10 Hz, noise, a random clock offset). The diagnosis then sees only
the nominal machine file and the logs. Printed: the confusion matrix (true effect x
verdict), top-1 accuracy where the effect is larger than three times the noise, the
verdict on cases without an effect, and the median held-out shrink of the gap.

The generator applies each effect to the prediction's per-consumer flows with its own
code, written from the physics (docs/reference/physics.md: cylinders, restrictions, what D4 adds) and sharing nothing with
the diagnosis' effect models: an exhaust is integrated as an ISO 6358 flow out of the dead
volume, a refill as an explicit exponential kernel, a meter as a step-by-step lag, a valve
delay as a dead time before the stroke.

    python bench/gap_blind.py [--cases 200] [--seed 1] [--effects leak,stroke_time] [--jobs N]

Cases are made in order from the seed and diagnosed in ``--jobs`` parallel processes
(default: every core). The physical tier is ``bench/gap_physical.py``.
"""
from __future__ import annotations

import argparse
import math
import os
import statistics
import sys
import time
from collections import Counter, defaultdict
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

import plcpred
from plcpred.diagnose import DiagnosisError, MeasuredRun, diagnose

ROOT = Path(__file__).resolve().parent.parent
MACHINES = ["samples/prototype_rig/rig.toml", "samples/prototype_rig/rig_seq2.toml",
            "samples/pick_place.toml", "samples/clamp_station.toml", "samples/press.toml",
            "samples/sorter.toml", "samples/cleaning.toml"]
EFFECTS = ["none", "leak", "passive_flow", "supply_pressure", "dead_volume",
           "incomplete_exhaust", "shared_supply", "valve_delay", "stroke_time", "sensor_lag"]
DT = 0.01
P0, T0, P_ATM = 100_000.0, 293.15, 101_325.0


# ---------------------------------------------------------------------- physics, ours

def iso6358_phi(r, b, m):
    """ISO 6358 subsonic flow function (docs/reference/physics.md D2)."""
    r = np.asarray(r, dtype=float)
    x = np.clip((r - b) / (1.0 - b), 0.0, 1.0)
    return np.where(r <= b, 1.0, (1.0 - x * x) ** m)


def exhaust_residual(v_dead_l, p_supply_pa, c_ex, t_avail_s):
    """Air (NL) left above atmosphere in a dead volume that started at supply pressure
    and exhausted isothermally through a restriction of conductance ``c_ex`` (ISO 6358,
    b = 0.3, m = 0.5) for ``t_avail_s``: dP/dt = -P_u C sqrt(T0/T) phi P0... integrated
    with small explicit steps."""
    p = p_supply_pa
    v_m3 = v_dead_l / 1000.0
    t = 0.0
    h = 1e-3
    while t < t_avail_s and p > P_ATM * 1.001:
        qm = 1.185 * c_ex * p * iso6358_phi(P_ATM / p, 0.3, 0.5)       # kg/s
        p -= qm * 287.05 * T0 / v_m3 * h                                 # isothermal
        t += h
    return max(p - P_ATM, 0.0) * v_m3 / P0 * 1000.0                      # NL


def meter(flow_l_min, tau_s, rate_hz, noise, offset_s, t_end, rng):
    """A thermal meter: lag integrated cell by cell, each logged sample the mean since
    the previous one, Gaussian noise; the logger's clock starts ``offset_s`` early."""
    y = np.empty(len(flow_l_min))
    state = 0.0
    k = math.exp(-DT / tau_s)
    for i, x in enumerate(flow_l_min.tolist()):
        state = x + (state - x) * k
        y[i] = state
    cum = np.concatenate([[0.0], np.cumsum(y) * DT])
    grid = np.arange(len(cum)) * DT
    dt = 1.0 / rate_hz
    ts = np.arange(dt, t_end, dt)
    q = (np.interp(ts, grid, cum) - np.interp(ts - dt, grid, cum)) / dt
    return ts + offset_s, q + rng.normal(0.0, noise, len(ts))


# a case's effect is measured after the best clock shift within this (the diagnosis
# aligns every log itself, so a pure shift is no effect it could see)
MAX_SHIFT_S = 2.0


def observable_size(t_s, q_with, q_without, max_shift_s=MAX_SHIFT_S):
    """RMS (NL/min) of what an effect changes in a log, after the best clock shift of the
    log without it. The logger's clock is unknown to the diagnosis, so an effect that only
    delays the whole machine (a valve delay where every step waits for the last) cannot be
    seen in the log; the part that a shift does not take out can. Shifts on a 5 ms grid,
    over the samples both logs cover (at least 80 %)."""
    t = np.asarray(t_s, dtype=float)
    q1, q0 = np.asarray(q_with, dtype=float), np.asarray(q_without, dtype=float)
    best = float(np.sqrt(np.mean((q1 - q0) ** 2)))
    for s in np.arange(-max_shift_s, max_shift_s + 1e-9, 0.005):
        ok = (t + s >= t[0]) & (t + s <= t[-1])
        if ok.sum() < 0.8 * len(t):
            continue
        best = min(best, float(np.sqrt(np.mean((q1[ok] - np.interp(t[ok] + s, t, q0)) ** 2))))
    return best


def strokes(pred, name):
    """(edge times, extend?) of a drive's valve changes, from the timeline."""
    model = next(m for m in pred.models if m.name == name)
    sig = pred.timeline.info.get("machine_signals", {}).get(model.valve[0], model.valve[0])
    t_ns, v = pred.timeline.edge_times_ns(sig)
    on = v != 0
    prev = np.concatenate([[model.initial_extended], on[:-1]])
    ch = on != prev
    return t_ns[ch] / 1e9, on[ch], model


def rect(n, start_s, dur_s, vol_nl):
    """NL/min on the grid of a volume spread evenly from start over dur."""
    out = np.zeros(n)
    t = np.arange(n) * DT
    for s, d, v in zip(start_s, dur_s, vol_nl):
        d = max(d, DT)
        lo = np.clip(t, s, s + d)
        hi = np.clip(t + DT, s, s + d)
        out += (hi - lo) / d * v / DT * 60.0
    return out


def truth_flow(pred, effect, rng, machine):
    """Total flow (NL/min on the grid) of the machine with the effect; the effect's
    description."""
    prof = pred.profile
    flows = prof.flow_l_min.copy()
    n = flows.shape[1]
    drives = [m.name for m in pred.models if m.role == "active"]
    nozzles = [m.name for m in pred.models if m.role == "passive"]
    mean = prof.mean_l_min
    p_s = machine.supply_bar_g * 1e5 + machine.atmosphere_kpa * 1000
    desc = {}
    if effect == "leak":
        q = mean * rng.uniform(0.05, 0.4)
        flows = np.vstack([flows, np.full(n, q)])
        desc = {"flow_l_min": q}
    elif effect == "passive_flow":
        k = prof.names.index(rng.choice(nozzles))
        f = rng.choice([rng.uniform(0.55, 0.85), rng.uniform(1.15, 1.6)])
        flows[k] *= f
        desc = {"nozzle": prof.names[k], "factor": f}
    elif effect == "supply_pressure":
        f = rng.choice([rng.uniform(0.7, 0.88), rng.uniform(1.12, 1.3)])
        p_new = P_ATM + (p_s - P_ATM) * f
        for i, m in enumerate(pred.models):
            if m.role == "active":
                flows[i] *= p_new / p_s                                  # D1
            else:
                c = machine.consumers[i]
                reg = None if c.pressure_bar_g is None else c.pressure_bar_g * 1e5 + P_ATM
                up_old = reg if reg is not None else p_s
                up_new = min(reg, p_new) if reg is not None else p_new
                b = c.b if c.b is not None else 0.528
                mm = c.m or 0.5
                phi = "choked" == c.flow_model
                ratio = up_new / up_old * (1.0 if phi else float(
                    iso6358_phi(P_ATM / up_new, b, mm) / iso6358_phi(P_ATM / up_old, b, mm)))
                flows[i] *= ratio                                        # D2
        desc = {"supply_bar_g": (p_new - P_ATM) / 1e5}
    elif effect in ("dead_volume", "incomplete_exhaust", "valve_delay", "stroke_time"):
        name = rng.choice(drives)
        i = prof.names.index(name)
        t, ext, model = strokes(pred, name)
        st = model.stroke_time_s or (0.0, 0.0)
        # air flows while the piston moves, after the valve's dead time
        start = t + model.delay_s
        dur = np.where(ext, st[0], st[1])
        vol = np.where(ext, model.extend_nl, model.retract_nl)
        if effect == "dead_volume":
            extra_cm3 = rng.uniform(0.3, 1.0) * vol.max() * 1000 / (p_s / P0)
            flows[i] += rect(n, start, dur, np.full(len(t), extra_cm3 / 1000 * p_s / P0))
            desc = {"drive": name, "extra_cm3": extra_cm3}
        elif effect == "incomplete_exhaust":
            c = machine.consumers[i]
            tube_l = [length * math.pi * (c.tube_id_mm or 4.0) ** 2 / 4 / 1000
                      for length in c.tube_length_m]
            v_dead = [max(x, 0.005) + 0.01 * vol.max() for x in tube_l]
            c_ex = rng.uniform(0.3e-9, 2e-9)
            saved = np.zeros(len(t))
            for k in range(1, len(t)):
                end_prev = start[k - 1] + dur[k - 1]
                vd = v_dead[0] if ext[k] else v_dead[1]
                saved[k] = exhaust_residual(vd, p_s, c_ex, max(0.0, t[k] - end_prev))
            flows[i] -= rect(n, start, dur, np.minimum(saved, vol))
            desc = {"drive": name, "exhaust_C": c_ex}
        elif effect == "valve_delay":
            d = rng.uniform(0.05, 0.3)
            shift = int(round(d / DT))
            flows[i] = np.concatenate([np.zeros(shift), flows[i][:-shift]])
            desc = {"drive": name, "delay_s": d}
        else:
            f = rng.choice([rng.uniform(0.3, 0.6), rng.uniform(1.8, 3.0)])
            new_dur = f * dur if model.stroke_time_s else np.full(len(t), 0.1 * f)
            flows[i] = rect(n, start, new_dur, vol)
            desc = {"drive": name, "factor": f}
    elif effect == "shared_supply":
        alpha = rng.uniform(0.15, 0.45)
        tau = rng.uniform(0.1, 0.8)
        kernel_t = np.arange(int(8 * tau / DT)) * DT
        kernel = np.exp(-kernel_t / tau)
        kernel /= kernel.sum()
        for name in drives:
            i = prof.names.index(name)
            t, ext, model = strokes(pred, name)
            st = model.stroke_time_s or (0.0, 0.0)
            ends = t + model.delay_s + np.where(ext, st[0], st[1])
            vol = np.where(ext, model.extend_nl, model.retract_nl) * alpha
            impulses = np.zeros(n)
            for e, v in zip(ends, vol):
                k = int(e / DT)
                if k < n:
                    impulses[k] += v / DT * 60.0
            flows[i] = flows[i] * (1 - alpha) + np.convolve(impulses, kernel)[:n]
        desc = {"fraction": alpha, "tau_s": tau}
    return flows.sum(axis=0), desc


def make_case(case_id, rng, effects):
    path = ROOT / MACHINES[case_id % len(MACHINES)]
    machine = plcpred.load_machine(path)
    has_nozzle = any(c.kind == "nozzle" for c in machine.consumers)
    drives = [c for c in machine.consumers if c.is_cylinder]
    usable = [e for e in effects
              if not (e == "passive_flow" and not has_nozzle)
              and not (e in ("dead_volume", "incomplete_exhaust", "valve_delay",
                             "stroke_time") and not drives)
              and not (e == "shared_supply" and len(drives) < 2)]
    if not usable:          # this machine cannot carry any of the effects asked for
        return None
    effect = usable[rng.integers(len(usable))]
    n_runs = int(rng.integers(1, 4))
    tau = rng.uniform(0.1, 0.6)
    rate = float(rng.choice([1.0, 2.0, 5.0, 10.0]))
    if effect == "sensor_lag":
        tau = rng.uniform(1.2, 4.0)
    runs, sizes, raw_sizes = [], [], []
    horizon = 60.0 if "rig.toml" not in str(path) else 20.0
    pred = plcpred.predict(machine, horizon + 5, dt=DT)
    flow, desc = truth_flow(pred, effect, rng, machine)
    nominal = pred.profile.total_flow_l_min
    noise = max(0.5, pred.profile.mean_l_min * rng.uniform(0.01, 0.04))
    for r in range(n_runs):
        offset = rng.uniform(0.0, 20.0)
        seed = int(rng.integers(1 << 31))
        t, q = meter(flow, tau, rate, noise, offset, horizon, np.random.default_rng(seed))
        base_tau = tau if effect != "sensor_lag" else rng.uniform(0.1, 0.6)
        _, q0 = meter(nominal, base_tau, rate, 0.0, offset, horizon,
                      np.random.default_rng(0))
        ts, q1 = meter(flow, tau, rate, 0.0, offset, horizon, np.random.default_rng(0))
        raw_sizes.append(float(np.sqrt(np.mean((q1 - q0) ** 2))))
        sizes.append(observable_size(ts, q1, q0))
        runs.append(MeasuredRun(f"case{case_id}_run{r}.csv", t, q))
    return {"id": case_id, "path": str(path), "machine": path.name, "effect": effect, "desc": desc,
            "runs": runs, "noise": noise, "size": float(np.mean(sizes)),
            "raw_size": float(np.mean(raw_sizes)),
            "meter": {"tau_s": tau, "rate_hz": rate}}


def write_sample_log(path, seed: int = 7) -> None:
    """The example log of docs/guide/diagnose.md: the rig's sequence 1 *with* its pilot leak (rig.toml)
    through a 2 Hz thermal meter (0.3 s lag, 1.5 NL/min noise) whose clock read 1000 s at
    the machine's start. Synthetic, not a measurement."""
    rng = np.random.default_rng(seed)
    pred = plcpred.predict(ROOT / "samples/prototype_rig/rig.toml", 45, dt=DT)
    t, q = meter(pred.profile.total_flow_l_min, 0.3, 2.0, 1.5, 1000.0, 45.0, rng)
    Path(path).write_text("time_s,flow_l_min\n" + "".join(
        f"{a:.1f},{b:.2f}\n" for a, b in zip(t, q)))


class Verdicts:
    """A blind benchmark's tally (shared with bench/gap_physical.py): the confusion
    matrix, top-1 where the withheld effect exceeds three times the noise (after the best
    clock shift, :func:`observable_size`), and the verdict on cases without one. A
    diagnosis that failed counts as the verdict ``error``."""

    def __init__(self):
        self.confusion = defaultdict(Counter)
        self.strong_hits = self.strong_n = self.none_hits = self.none_n = 0
        self.per_effect = defaultdict(lambda: [0, 0])    # effect > 3x noise: [hits, cases]
        self.shifted = []       # (truth, verdict): strong only before the clock shift

    def add(self, truth: str, verdict: str, strong: bool, strong_unshifted: bool = False):
        self.confusion[truth][verdict] += 1
        if strong_unshifted and not strong and truth != "none":
            self.shifted.append((truth, verdict))
        if truth == "none":
            self.none_n += 1
            self.none_hits += verdict == "none"
        elif strong:
            self.strong_n += 1
            self.strong_hits += verdict == truth
            self.per_effect[truth][0] += verdict == truth
            self.per_effect[truth][1] += 1

    def print(self, cases: int, effects: list[str], target_pct: float,
              width: int = 19) -> None:
        c = self.confusion
        names = [e for e in effects + ["error"]
                 if e in c or any(e in row for row in c.values())]
        print(f"\nconfusion matrix ({cases} cases, rows: withheld effect, columns: verdict)")
        print(f"{'':<{width}}" + "".join(f"{e[:6]:>7}" for e in names))
        for e in names:
            if e in c:
                print(f"{e:<{width}}" + "".join(f"{c[e][v]:>7}" for v in names))
        print()
        if self.strong_n:
            print(f"top-1 accuracy, effect > 3x noise: {self.strong_hits}/{self.strong_n} = "
                  f"{100 * self.strong_hits / self.strong_n:.1f} % "
                  f"(target >= {target_pct:g} %)")
            print("  by effect: " + ", ".join(f"{e} {h}/{n}" for e, (h, n) in
                                              sorted(self.per_effect.items())))
        if self.shifted:
            hits = sum(t == v for t, v in self.shifted)
            print(f"  not counted: {len(self.shifted)} more exceed 3x noise only before the "
                  f"best clock shift ({hits} of them named)")
        if self.none_n:
            print(f"verdict none without an effect:    {self.none_hits}/{self.none_n} = "
                  f"{100 * self.none_hits / self.none_n:.1f} % (target >= 90 %)")


def diagnose_case(case) -> dict:
    """What the summary needs of one case's diagnosis (run in a worker process)."""
    t0 = time.process_time()
    try:
        d = diagnose(plcpred.load_machine(case["path"]), case["runs"])
    except DiagnosisError as e:
        return {"error": str(e), "cpu_s": time.process_time() - t0}
    base = d.baseline_heldout
    after = None if not d.effects else (d.effects[0].heldout_score if d.verdict != "none"
                                        else base)
    return {"verdict": d.verdict, "noise": d.noise_l_min, "base_mse": base.mse,
            "base_error_pct": base.error_pct,
            "after_mse": None if after is None else after.mse,
            "after_error_pct": None if after is None else after.error_pct,
            "cpu_s": time.process_time() - t0}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sample-log", metavar="PATH",
                    help="only write the synthetic example log of docs/guide/diagnose.md to PATH")
    ap.add_argument("--cases", type=int, default=200)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--effects", help="withhold only these (comma-separated)")
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 1,
                    help="processes diagnosing cases in parallel (default: every core)")
    ap.add_argument("--verbose", action="store_true")
    args = ap.parse_args(argv)
    if args.sample_log:
        write_sample_log(args.sample_log)
        return 0
    effects = args.effects.split(",") if args.effects else EFFECTS
    rng = np.random.default_rng(args.seed)
    verdicts = Verdicts()
    shrinks, volume_shrinks = [], []
    errors = []
    t0 = time.perf_counter()
    cases, k = [], 0
    while len(cases) < args.cases:
        case = make_case(k, rng, effects)
        k += 1
        if case is not None:
            cases.append(case)
        elif k > 10 * args.cases + len(MACHINES):
            ap.error(f"no sample machine can carry {args.effects}")
    # cases are independent: diagnosed in parallel processes, in order
    with ProcessPoolExecutor(max_workers=args.jobs) as pool:
        outcomes = list(pool.map(diagnose_case, cases))
    cpu = 0.0
    for i, (case, out) in enumerate(zip(cases, outcomes)):
        truth = case["effect"]
        cpu += out["cpu_s"]
        strong = case["size"] > 3 * case["noise"]
        unshifted = case["raw_size"] > 3 * case["noise"]
        if "error" in out:     # counted as a miss, named in the output
            verdicts.add(truth, "error", strong, unshifted)
            errors.append(f"case {i} ({case['machine']}, {truth}): {out['error']}")
            continue
        verdict = out["verdict"]
        verdicts.add(truth, verdict, strong, unshifted)
        if truth != "none" and strong and out["after_mse"] is not None:
            noise2 = out["noise"] ** 2
            excess_before = math.sqrt(max(out["base_mse"] - noise2, 1e-12))
            excess_after = math.sqrt(max(out["after_mse"] - noise2, 0.0))
            shrinks.append(1.0 - excess_after / excess_before)
            if abs(out["base_error_pct"]) > 2.0:
                volume_shrinks.append(1.0 - abs(out["after_error_pct"])
                                      / abs(out["base_error_pct"]))
        if args.verbose:
            print(f"{i:4d} {case['machine']:<20} {truth:<19} -> {verdict:<19} size/noise "
                  f"{case['size'] / case['noise']:5.1f} {out['cpu_s']:5.1f} s {case['desc']}",
                  flush=True)
    wall = time.perf_counter() - t0
    verdicts.print(args.cases, EFFECTS, target_pct=95)
    if shrinks:
        print(f"median held-out shrink of the excess RMSE: {100 * statistics.median(shrinks):.0f} %"
              f" (target >= 70 %)")
    if volume_shrinks:
        print(f"median held-out shrink of the NL gap (gaps > 2 %): "
              f"{100 * statistics.median(volume_shrinks):.0f} %")
    for e in errors:
        print(f"error: {e}")
    print(f"{args.cases} cases in {wall:.0f} s on {args.jobs} processes "
          f"({cpu / max(args.cases, 1):.1f} s of CPU per case)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
