"""Generate diagnosis cases from the independent physics (bench/indep/physics.py).

    python bench/indep/generate.py --out DIR --cases N --seed S [--machines a,b] [--jobs J]

One folder per case: machine.toml (+ its program: the NOMINAL machine the diagnosis
sees), run1.csv, run2.csv, run3.csv (flow logs time_s,flow_l_min,supply_bar_g in NL/min
at ISO 8778; run3 is held back from the diagnosis), run1.timeline.csv ... (the real valve
edges on the machine's clock, usable as `--io` traces) and case.json (the ground truth).

How a case is made (see README.md in this folder):
1. draw the machine, the category and the effect(s), and the hidden physics every real
   machine has (valve sizes, ramps and delays, friction, heat transfer, dead volumes,
   tube friction, nozzle conductances, ambient, meter);
2. commission the healthy machine: each drive's meter-out flow controls are turned down
   until its strokes take the machine file's stroke times (within +-7 %, as measured by
   a technician), in the physics;
3. apply the effect(s) (a throttled drive, longer tubes, a later valve, a leak, ...);
4. measure each drive's real stroke times in the physics, write a copy of the machine
   file with those stroke times and switching delays (and each run's own input seeds)
   and run `plcpred timeline` on it: the real valve edges;
5. simulate every run in the physics on those edges, log it through the meter.
Only `plcpred timeline` (a documented CLI) is used from plcpred.
"""
from __future__ import annotations

import argparse
import copy
import hashlib
import json
import math
import multiprocessing as mp
import os
import shutil
import subprocess
import sys
import tempfile
import time
import tomllib
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent.parent
sys.path.insert(0, str(HERE))
import physics as ph  # noqa: E402

PLCPRED = str(Path(sys.executable).with_name("plcpred")) if Path(sys.executable).with_name("plcpred").exists() \
    else (shutil.which("plcpred") or "plcpred")

DRIVE_KINDS = ("double_acting", "single_acting", "double_rod", "rodless", "semi_rotary", "gripper")

# Machines. For the samples, what their files do not say about the real machine (payload,
# mount) is drawn from these ranges; our own machines state payload_kg/mount_angle_deg.
MACHINES = {
    "packer": {"toml": HERE / "machines" / "packer.toml", "hidden": {}},
    "pressfit": {"toml": HERE / "machines" / "pressfit.toml", "hidden": {}},
    "pick_place": {"toml": ROOT / "samples" / "pick_place.toml", "hidden": {
        "Z lift": {"payload_kg": (0.4, 1.0), "mount_angle_deg": -90.0},
        "X slide": {"payload_kg": (1.5, 3.0)},
        "gripper": {"payload_kg": (0.0, 0.03)},
    }},
    "clamp_station": {"toml": ROOT / "samples" / "clamp_station.toml", "hidden": {
        "clamp": {"payload_kg": (0.2, 0.6)},
        "drill feed": {"payload_kg": (2.5, 5.0), "mount_angle_deg": -90.0},
    }},
}

IN_LIBRARY = ["leak", "passive_flow", "supply_pressure", "dead_volume", "valve_delay", "stroke_time",
              "sensor_lag", "shared_supply"]
OUT_OF_LIBRARY = ["stuck_on_valve", "meter_gain", "regulator_droop", "din1343_meter"]
TIME_LOCAL = ["leak", "stuck_on_valve", "supply_pressure"]
TIMELINE_HORIZON_S = 185.0
CATEGORY_MIX = [("healthy", 0.25), ("in_library", 0.35), ("two_effects", 0.15), ("time_localised", 0.10),
                ("out_of_library", 0.15)]


# ---- TOML writing (the subset machine files use) ---------------------------------------------

def _key(k):
    return k if k.replace("_", "").replace("-", "").isalnum() and k[:1].isalpha() else json.dumps(k)


def _val(v):
    if isinstance(v, np.generic):
        v = v.item()
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_val(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{_key(k)} = {_val(x)}" for k, x in v.items()) + " }"
    raise TypeError(type(v))


def dump_toml(doc: dict, header: str = "") -> str:
    out = [header] if header else []
    tables = [(k, v) for k, v in doc.items() if isinstance(v, dict)]
    arrays = [(k, v) for k, v in doc.items() if isinstance(v, list) and v and isinstance(v[0], dict)]
    for k, v in tables:
        out.append(f"[{_key(k)}]")
        out += [f"{_key(a)} = {_val(b)}" for a, b in v.items()]
        out.append("")
    for k, lst in arrays:
        for item in lst:
            out.append(f"[[{_key(k)}]]")
            out += [f"{_key(a)} = {_val(b)}" for a, b in item.items()]
            out.append("")
    return "\n".join(out)


# ---- the machine as a user wrote it ------------------------------------------------------------

def load_machine(name):
    info = MACHINES[name]
    path = Path(info["toml"])
    doc = tomllib.loads(path.read_text())
    return path, doc


def nominal_restriction(c):
    """C, b, m of a nozzle or leak as its file gives it (D2 keys or an orifice)."""
    if "C" in c:
        return float(c["C"]), float(c["b"]), float(c.get("m", 0.5))
    return ph.c_orifice(float(c["orifice_mm"]), float(c["Cd"])), 0.528, float(c.get("m", 0.5))


def tube_lengths(c):
    tl = c.get("tube_length_m", 0.0)
    if isinstance(tl, (list, tuple)):
        return float(tl[0]), float(tl[1])
    return float(tl), float(tl)


def stroke_file(c):
    st = c.get("stroke_time_s")
    if st is None or st == "auto":
        return None
    if isinstance(st, (list, tuple)):
        return float(st[0]), float(st[1])
    return float(st), float(st)


def valve_signals(c):
    v = c.get("valve")
    if v is None:
        return []
    return list(v) if isinstance(v, (list, tuple)) else [v]


# ---- timelines -----------------------------------------------------------------------------------

def read_timeline(path):
    sig = {}
    with open(path) as f:
        next(f)
        for line in f:
            t, s, v = line.rstrip("\n").split(",", 2)
            try:
                val = float(v)
            except ValueError:
                val = 1.0 if v.strip().lower() in ("true", "1") else 0.0
            sig.setdefault(s, []).append((float(t), val))
    return sig


def consumer_edges(c, sig):
    """(initial state, [(t_command, state)]) of a consumer's valve from a timeline: monostable
    (state = output) or bistable (rising edge of the first solenoid sets, of the second
    resets; both in the same scan: no move; a pulse that does not change the state is no
    edge), docs/reference/physics.md, cylinders (D1) edge rules."""
    vs = valve_signals(c)
    init = 1 if c.get("initial", "retracted") == "extended" else 0
    if not vs:
        return init, []
    if len(vs) == 1:
        # monostable: the output's value at 0 is the initial state, each change an edge
        ch = sig.get(vs[0], [])
        if not ch:
            return 0, []
        state = 1 if ch[0][1] > 0.5 else 0
        init = state
        edges = []
        for t, v in ch[1:]:
            b = 1 if v > 0.5 else 0
            if b != state:
                edges.append((t, b))
                state = b
        return init, edges
    a = sig.get(vs[0], [])
    b = sig.get(vs[1], [])
    ev = sorted([(t, 0, v) for t, v in a] + [(t, 1, v) for t, v in b])
    last = {0: 0.0, 1: 0.0}
    state = init
    edges = []
    i = 0
    while i < len(ev):
        t = ev[i][0]
        rising = set()
        while i < len(ev) and ev[i][0] == t:
            _, which, v = ev[i]
            if v > 0.5 and last[which] <= 0.5 and t > 0.0:
                rising.add(which)
            last[which] = v
            i += 1
        if rising == {0} and state != 1:
            state = 1
            edges.append((t, 1))
        elif rising == {1} and state != 0:
            state = 0
            edges.append((t, 0))
    return init, edges


_TL_CACHE = {}


def run_timeline(doc, prog_src: Path, horizon, workdir: Path):
    """Write `doc` (a machine file as a dict) next to a copy of its program and run
    `plcpred timeline` on it. Cached by content."""
    text = dump_toml(doc, "# real machine (bench/indep generator): real stroke times, delays, input seeds")
    key = hashlib.sha1((text + f"|{horizon:.3f}|" + str(prog_src)).encode()).hexdigest()[:16]
    if key in _TL_CACHE:
        return _TL_CACHE[key]
    d = workdir / f"tl_{key}"
    d.mkdir(parents=True, exist_ok=True)
    shutil.copy(prog_src, d / prog_src.name)
    (d / "machine.toml").write_text(text)
    cmd = [PLCPRED, "timeline", str(d / "machine.toml"), "--horizon", f"{horizon:.3f}", "--out", str(d / "out")]
    p = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    if p.returncode != 0:
        raise RuntimeError(f"plcpred timeline failed ({p.returncode}): {p.stderr.strip()[:500]}")
    _TL_CACHE[key] = d / "out" / "timeline.csv"
    return _TL_CACHE[key]


# ---- drawing a case ------------------------------------------------------------------------------

def draw_categories(n, rng):
    counts = [int(round(n * w)) for _, w in CATEGORY_MIX]
    while sum(counts) > n:
        counts[int(np.argmax(counts))] -= 1
    while sum(counts) < n:
        counts[1] += 1
    cats = [c for (c, _), k in zip(CATEGORY_MIX, counts) for _ in range(k)]
    rng.shuffle(cats)
    return cats


def U(rng, a, b):
    return float(rng.uniform(a, b))


def logU(rng, a, b):
    return float(math.exp(rng.uniform(math.log(a), math.log(b))))


class Case:
    pass


def nominal_active_nozzles(path, doc, workdir):
    """Nozzles the nominal program ever switches on (over 60 s)."""
    tl = run_timeline(doc, path.parent / doc["machine"]["program"], 60.0, workdir)
    sig = read_timeline(tl)
    out = []
    for c in doc.get("consumer", []):
        if c["kind"] == "nozzle":
            _, e = consumer_edges(c, sig)
            if any(s == 1 for _, s in e):
                out.append(c["name"])
    return out


def draw_case(idx, category, machine, seed, workdir, active_cache):
    rng = np.random.default_rng([seed, idx, 7])
    path, doc = load_machine(machine)
    cs = Case()
    cs.idx, cs.category, cs.machine, cs.path, cs.doc = idx, category, machine, path, doc
    m = doc["machine"]
    cs.supply_g = float(m["supply_bar_g"])
    cs.atm_file = float(m.get("atmosphere_kpa", 101.325)) * 1e3
    cs.t_file = float(m.get("ambient_c", 20.0)) + 273.15
    drives = [c for c in doc.get("consumer", []) if c["kind"] in DRIVE_KINDS]
    nozzles = [c for c in doc.get("consumer", []) if c["kind"] == "nozzle"]
    leaks = [c for c in doc.get("consumer", []) if c["kind"] == "leak"]
    cs.drives_doc, cs.nozzles_doc, cs.leaks_doc = drives, nozzles, leaks
    if machine not in active_cache:
        active_cache[machine] = nominal_active_nozzles(path, doc, workdir)
    active = active_cache[machine]
    hidden = MACHINES[machine]["hidden"]

    # --- the hidden physics of every real machine
    pert = {"drives": {}, "nozzles": {}, "leaks": {}}
    cs.p_atm = cs.atm_file + U(rng, -1500, 1500)
    cs.t_amb = cs.t_file + U(rng, -3, 3)
    cs.t_sup = cs.t_amb + U(rng, -1, 4)
    cs.p_set = cs.p_atm + cs.supply_g * 1e5 + U(rng, -0.05, 0.05) * 1e5   # regulator set point accuracy
    pert.update(p_atm=cs.p_atm, t_amb=cs.t_amb, t_sup=cs.t_sup, p_set_abs=cs.p_set)
    cs.dspecs = {}
    cs.targets = {}
    for c in drives:
        name = c["name"]
        lt = tube_lengths(c)
        hid = hidden.get(name, {})
        payload = c.get("payload_kg")
        payload = float(payload) * U(rng, 0.85, 1.15) if payload is not None else (
            U(rng, *hid["payload_kg"]) if "payload_kg" in hid else U(rng, 0.0, 0.2))
        mount = float(c.get("mount_angle_deg", hid.get("mount_angle_deg", 0.0)))
        bore = float(c["bore_mm"])
        cv = 1.2e-8 * (bore / 32.0) ** 0.8 * U(rng, 0.8, 1.25)
        # Coulomb friction as a share of the cap force at 6 bar; a single-acting drive's seals
        # are chosen to let its spring return it (spring preload above breakaway)
        fc = (U(rng, 0.02, 0.04) if c["kind"] == "single_acting" else U(rng, 0.03, 0.08)) \
            * math.pi * (bore * 1e-3) ** 2 / 4 * 6e5
        d = ph.DriveSpec(
            name=name, kind=c["kind"], bore_mm=bore, rod_mm=float(c.get("rod_mm", 0.0)),
            stroke_mm=float(c["stroke_mm"]), tube_id_mm=float(c.get("tube_id_mm", 0.0)), tube_len_m=lt,
            dead_len_mm=(U(rng, 1.0, 3.0), U(rng, 1.0, 3.0)),
            c_valve=max(cv, 4e-9), b_valve=U(rng, 0.2, 0.4), m_valve=U(rng, 0.45, 0.6),
            tube_lambda=U(rng, 0.018, 0.035), overlap=U(rng, 0.1, 0.3), ramp_s=U(rng, 0.005, 0.025),
            delay_s=max(0.004, float(c.get("switch_delay_s", 0.0)) + U(rng, -0.010, 0.010)),
            wave_c=U(rng, 300.0, 360.0), h_cyl=logU(rng, 12.0, 80.0), h_tube=logU(rng, 25.0, 150.0),
            payload_kg=payload, mount_angle_deg=mount,
            f_coulomb=(fc, fc * U(rng, 0.8, 1.2)), static_ratio=U(rng, 1.2, 1.7), viscous_ns_m=fc / U(rng, 0.3, 1.0),
            stribeck_v=U(rng, 0.01, 0.04), spring_bar=(U(rng, 0.5, 0.7), U(rng, 1.0, 1.4)),
            initial=c.get("initial", "retracted"))
        cs.dspecs[name] = d
        sf = stroke_file(c)
        cs.targets[name] = None if sf is None else (sf[0] * U(rng, 0.93, 1.07), sf[1] * U(rng, 0.93, 1.07))
        pert["drives"][name] = {k: getattr(d, k) for k in (
            "c_valve", "b_valve", "m_valve", "tube_lambda", "overlap", "ramp_s", "delay_s", "wave_c", "h_cyl",
            "h_tube", "payload_kg", "mount_angle_deg", "f_coulomb", "static_ratio", "viscous_ns_m", "stribeck_v",
            "dead_len_mm", "spring_bar")}
        pert["drives"][name]["commission_target_s"] = cs.targets[name]
    cs.rspecs = {}
    for c in nozzles:
        C, b, mm = nominal_restriction(c)
        f = U(rng, 0.9, 1.1)
        preg = (cs.p_atm + float(c["pressure_bar_g"]) * 1e5 + U(rng, -0.05, 0.05) * 1e5) if "pressure_bar_g" in c else None
        r = ph.RestrictionSpec(name=c["name"], C=C * f, b=min(max(b + U(rng, -0.05, 0.03), 0.05), 0.6),
                               m=mm + U(rng, -0.03, 0.05), p_reg_abs=preg, edges=[],
                               delay_s=U(rng, 0.008, 0.022), ramp_s=U(rng, 0.005, 0.025))
        cs.rspecs[c["name"]] = r
        pert["nozzles"][c["name"]] = {"C": r.C, "C_factor": f, "b": r.b, "m": r.m, "p_reg_abs": preg,
                                      "delay_s": r.delay_s, "ramp_s": r.ramp_s}
    cs.lspecs = {}
    for c in leaks:
        C, b, mm = nominal_restriction(c)
        f = U(rng, 0.9, 1.1)
        preg = (cs.p_atm + float(c["pressure_bar_g"]) * 1e5) if "pressure_bar_g" in c else None
        cs.lspecs[c["name"]] = ph.RestrictionSpec(name=c["name"], C=C * f, b=b, m=mm, p_reg_abs=preg, edges=None)
        pert["leaks"][c["name"]] = {"C": C * f, "C_factor": f}
    # meter, runs
    cs.meter = {"tau_s": U(rng, 0.1, 0.6), "rate_hz": float(rng.choice([1.0, 2.0, 2.0, 5.0, 10.0])),
                "noise_frac": U(rng, 0.01, 0.03), "jitter_frac": U(rng, 0.0, 0.1), "gain": 1.0,
                "reference": "iso8778", "p_noise_bar": U(rng, 0.005, 0.015)}
    cs.runs = []
    jittered = [i for i, x in enumerate(doc.get("input", [])) if float(x.get("jitter_s", 0)) > 0]
    for r in range(3):
        t_len = float(round(U(rng, 60.0, 180.0)))       # with t_start <= 3 s: ends before TIMELINE_HORIZON_S
        cs.runs.append({"t_start": round(U(rng, 0.5, 3.0), 3), "t_len": t_len, "clock_offset": round(U(rng, 0.0, 20.0), 3),
                        "seeds": {i: int(1000 * (idx + 1) + 10 * r + k + seed * 100003) % 2_000_000_000
                                  for k, i in enumerate(jittered)}})
    cs.jittered = bool(jittered)
    cs.pert = pert

    # --- the effect(s)
    eff = []
    drive_names = list(cs.dspecs)
    timed = [n for n in drive_names if cs.targets[n] is not None]
    tubed = [n for n in drive_names if max(cs.dspecs[n].tube_len_m) > 0]

    def draw_inlib(name, avoid=()):
        if name == "leak":
            return {"name": "leak", "parameters": {"C": logU(rng, 3e-10, 1.5e-9), "b": U(rng, 0.1, 0.45), "m": U(rng, 0.5, 0.9)}}
        if name == "passive_flow":
            f = U(rng, 0.6, 0.8) if rng.random() < 0.5 else U(rng, 1.2, 1.5)
            return {"name": name, "consumer": str(rng.choice(active)), "parameters": {"factor": f}}
        if name == "supply_pressure":
            dp = U(rng, 0.4, 1.0) * (1 if rng.random() < 0.5 else -1)
            return {"name": name, "parameters": {"delta_bar": dp, "supply_bar_g": cs.supply_g + dp}}
        if name == "dead_volume":
            return {"name": name, "consumer": str(rng.choice([n for n in tubed if n not in avoid] or tubed)),
                    "parameters": {"tube_factor": U(rng, 2.0, 4.0)}}
        if name == "valve_delay":
            return {"name": name, "parameters": {"extra_s": U(rng, 0.03, 0.08)}}
        if name == "stroke_time":
            return {"name": name, "consumer": str(rng.choice([n for n in timed if n not in avoid] or timed)),
                    "parameters": {"factor": U(rng, 1.5, 2.5)}}
        if name == "sensor_lag":
            return {"name": name, "parameters": {"tau_s": U(rng, 1.2, 4.0)}}
        if name == "shared_supply":
            return {"name": name, "parameters": {"line_volume_l": U(rng, 0.05, 0.25), "reg_C_factor": U(rng, 0.35, 0.8),
                                                 "reg_band_bar": U(rng, 0.2, 0.5), "network_above_bar": U(rng, 1.0, 2.0)}}
        raise ValueError(name)

    lib = [n for n in IN_LIBRARY if not (n == "passive_flow" and not active)]
    if category == "healthy":
        expected = ["none"]
    elif category == "in_library":
        e = draw_inlib(str(rng.choice(lib)))
        eff.append(e)
        expected = [e["name"]]
    elif category == "two_effects":
        a, b = rng.choice(lib, size=2, replace=False)
        e1 = draw_inlib(str(a))
        e2 = draw_inlib(str(b), avoid=(e1.get("consumer"),))
        eff += [e1, e2]
        expected = [e1["name"], e2["name"]]
    elif category == "time_localised":
        kind = str(rng.choice(TIME_LOCAL))
        r0 = cs.runs[0]
        onset = round(r0["t_start"] + U(rng, 0.2, 0.8) * r0["t_len"], 3)
        if kind == "leak":
            e = draw_inlib("leak")
            e["parameters"]["C"] = logU(rng, 6e-10, 1.5e-9)
            expected = ["leak"]
        elif kind == "stuck_on_valve":
            e = {"name": "stuck_on_valve", "consumer": str(rng.choice([c["name"] for c in nozzles])), "parameters": {}}
            expected = ["leak", "passive_flow"]
        else:
            e = {"name": "supply_pressure", "parameters": {"delta_bar": -U(rng, 0.5, 1.0)}}
            e["parameters"]["supply_bar_g"] = cs.supply_g + e["parameters"]["delta_bar"]
            expected = ["supply_pressure"]
        e["onset_s"] = onset
        e["onset_run"] = 1
        e["onset_logger_s"] = round(onset + r0["clock_offset"], 3)
        e["onset_fraction_of_log"] = (onset - r0["t_start"]) / r0["t_len"]
        eff.append(e)
    else:
        kind = str(rng.choice(OUT_OF_LIBRARY))
        if kind == "stuck_on_valve":
            e = {"name": kind, "consumer": str(rng.choice([c["name"] for c in nozzles])), "parameters": {}}
        elif kind == "meter_gain":
            e = {"name": kind, "parameters": {"gain": U(rng, 1.05, 1.15)}}
        elif kind == "regulator_droop":
            e = {"name": kind, "parameters": {"drop_at_mean_bar": U(rng, 0.15, 0.4), "tau_s": U(rng, 0.1, 0.3)}}
        else:
            e = {"name": kind, "parameters": {"reference": "din1343", "factor": ph.DIN1343_FACTOR}}
        eff.append(e)
        expected = ["none", "unexplained"]
    for e in eff:
        e.setdefault("onset_s", None)
        e.setdefault("consumer", None)
    cs.effects = eff
    cs.expected = expected
    return cs


# ---- the pipeline ----------------------------------------------------------------------------------

def effect(cs, name):
    for e in cs.effects:
        if e["name"] == name:
            return e
    return None


def build_chunk(args_tuple):
    ids, cats, machs, seed, out, dt, quiet = args_tuple
    t0 = time.time()
    log = (lambda *a: None) if quiet else (lambda *a: print(f"[pid {os.getpid()}]", *a, flush=True))
    work = Path(tempfile.mkdtemp(prefix="indep_gen_"))
    try:
        active = {}
        cases = [draw_case(i, c, m, seed, work, active) for i, c, m in zip(ids, cats, machs)]
        log(f"{len(cases)} cases drawn ({time.time()-t0:.0f} s)")

        # 2. commissioning of the healthy machines
        items, targets, owners = [], [], []
        for cs in cases:
            for n, d in cs.dspecs.items():
                # a valve too small for the stroke time asked: a larger one (checked open)
                items.append((d, cs.p_set, cs.p_atm, cs.t_amb))
                targets.append(cs.targets[n])
                owners.append((cs, n))
        for _ in range(3):
            st = ph.stroke_times(items, dt=dt)
            grow = False
            for k, ((cs, n), tg, s) in enumerate(zip(owners, targets, st)):
                if tg is None:
                    continue
                worst = max((s[j] / (0.85 * tg[j])) if not math.isnan(s[j]) else 3.0 for j in (0, 1))
                if worst > 1.0:
                    d = cs.dspecs[n]
                    d.c_valve *= min(3.0, worst ** 1.5)
                    items[k] = (d,) + items[k][1:]
                    grow = True
            if not grow:
                break
        comm, st = ph.commission(items, targets, dt=dt)
        for (cs, n), d, s in zip(owners, comm, st):
            cs.dspecs[n] = d
            cs.pert["drives"][n]["c_valve"] = d.c_valve
            cs.pert["drives"][n]["c_throttle"] = d.c_throttle
            cs.pert["drives"][n]["c_meter_in"] = d.c_meter_in
            cs.pert["drives"][n]["commissioned_stroke_s"] = [float(s[0]), float(s[1])]
        log(f"commissioned {len(items)} drives ({time.time()-t0:.0f} s)")

        # 3. the effects that change the drives
        items, targets, owners = [], [], []
        for cs in cases:
            e = effect(cs, "stroke_time")
            if e:
                n = e["consumer"]
                cst = cs.pert["drives"][n]["commissioned_stroke_s"]
                items.append((cs.dspecs[n], cs.p_set, cs.p_atm, cs.t_amb))
                targets.append((cst[0] * e["parameters"]["factor"], cst[1] * e["parameters"]["factor"]))
                owners.append((cs, n))
            e = effect(cs, "dead_volume")
            if e:
                d = cs.dspecs[e["consumer"]]
                f = e["parameters"]["tube_factor"]
                cs.dspecs[e["consumer"]] = ph._clone(d, tube_len_m=(d.tube_len_m[0] * f, d.tube_len_m[1] * f))
            e = effect(cs, "valve_delay")
            if e:
                x = e["parameters"]["extra_s"]
                for n, d in cs.dspecs.items():
                    cs.dspecs[n] = ph._clone(d, delay_s=d.delay_s + x)
                for r in cs.rspecs.values():
                    r.delay_s += x
            e = effect(cs, "passive_flow")
            if e:
                cs.rspecs[e["consumer"]].C *= e["parameters"]["factor"]
        if items:
            slowed, st = ph.commission(items, targets, dt=dt)
            for (cs, n), d, s in zip(owners, slowed, st):
                cs.dspecs[n] = d
                e = effect(cs, "stroke_time")
                e["parameters"]["stroke_s"] = [float(s[0]), float(s[1])]
                e["parameters"]["c_throttle"] = d.c_throttle
                e["parameters"]["c_meter_in"] = d.c_meter_in

        # supply of each run
        for cs in cases:
            p_real = cs.p_set
            e = effect(cs, "supply_pressure")
            cs.run_supply = []
            for r in range(3):
                sp = ph.SupplySpec(p_set_abs=p_real)
                if e is not None:
                    p_new = p_real + e["parameters"]["delta_bar"] * 1e5
                    if e.get("onset_s") is not None and r == 0:
                        sp.schedule = [(e["onset_s"], p_new)]
                    else:
                        sp.p_set_abs = p_new
                cs.run_supply.append(sp)
            e = effect(cs, "shared_supply")
            if e:
                p = e["parameters"]
                # the regulator's conductance against the largest drive's supply path (valve + tube)
                cmax = max(ph.series([d.c_valve] + ([ph.c_tube(d.tube_id_mm, d.tube_len_m[0], d.tube_lambda)]
                                                     if d.tube_len_m[0] > 0 else []),
                                     [d.b_valve, 0.45][:1 + (d.tube_len_m[0] > 0)])[0] for d in cs.dspecs.values())
                for sp in cs.run_supply:
                    sp.mode = "line"
                    sp.line_volume_l = p["line_volume_l"]
                    sp.reg_C = p["reg_C_factor"] * cmax
                    sp.reg_band_pa = p["reg_band_bar"] * 1e5
                    sp.network_abs = sp.p_set_abs + p["network_above_bar"] * 1e5
                p["reg_C"] = p["reg_C_factor"] * cmax

        # 4. real stroke times per supply condition -> timelines
        items, owners = [], []
        for cs in cases:
            cs.real_st = [{} for _ in range(3)]
            for r in range(3):
                sp = cs.run_supply[r]
                p = sp.p_set_abs   # a run whose supply drops later: the stroke times before the drop
                for n, d in cs.dspecs.items():
                    items.append((d, p, cs.p_atm, cs.t_amb))
                    owners.append((cs, r, n))
        st = ph.stroke_times(items, dt=dt)
        for (cs, r, n), s in zip(owners, st):
            cs.real_st[r][n] = s
        log(f"stroke times measured ({time.time()-t0:.0f} s)")

        for cs in cases:
            cs.timelines = []
            prog = cs.path.parent / cs.doc["machine"]["program"]
            for r in range(3):
                doc = copy.deepcopy(cs.doc)
                for c in doc.get("consumer", []):
                    if c["name"] in cs.dspecs:
                        d = cs.dspecs[c["name"]]
                        s = cs.real_st[r][c["name"]]
                        if "stroke_time_s" in c:
                            ext = s[0] if not math.isnan(s[0]) else 30.0
                            ret = s[1] if not math.isnan(s[1]) else 30.0
                            c["stroke_time_s"] = [round(float(max(ext, 0.005)), 3), round(float(max(ret, 0.005)), 3)]
                        c["switch_delay_s"] = round(float(d.delay_s), 3)
                for k, x in enumerate(doc.get("input", [])):
                    if k in cs.runs[r]["seeds"]:
                        x["seed"] = cs.runs[r]["seeds"][k]
                # one horizon for every run (runs end by 184 s): a shorter run's edges are a
                # prefix, and runs whose machine files are the same share one timeline
                cs.timelines.append(run_timeline(doc, prog, TIMELINE_HORIZON_S, work))
        log(f"timelines written ({time.time()-t0:.0f} s)")

        # 5. runs in the physics
        specs, owners = [], []
        for cs in cases:
            cs.edges = []
            for r in range(3):
                sig = read_timeline(cs.timelines[r])
                run = cs.runs[r]
                drives = []
                edges_r = {}
                for c in cs.drives_doc:
                    init, ed = consumer_edges(c, sig)
                    edges_r[c["name"]] = ed
                    d = ph._clone(cs.dspecs[c["name"]], edges=ed, initial="extended" if init else "retracted")
                    drives.append(d)
                restr = []
                for c in cs.nozzles_doc:
                    init, ed = consumer_edges(c, sig)
                    if init:
                        ed = [(0.0, 1)] + ed
                    edges_r[c["name"]] = ed
                    x = copy.copy(cs.rspecs[c["name"]])
                    x.edges = ed
                    e = effect(cs, "stuck_on_valve")
                    if e and e["consumer"] == c["name"]:
                        x.stuck_on_from = (e["onset_s"] if (e["onset_s"] is not None and r == 0) else 0.0)
                    restr.append(x)
                for c in cs.leaks_doc:
                    restr.append(copy.copy(cs.lspecs[c["name"]]))
                e = effect(cs, "leak")
                if e:
                    p = e["parameters"]
                    restr.append(ph.RestrictionSpec(name="hidden leak", C=p["C"], b=p["b"], m=p["m"], edges=None,
                                                    onset_s=(e["onset_s"] if (e["onset_s"] is not None and r == 0) else None)))
                sp = copy.copy(cs.run_supply[r])
                e = effect(cs, "regulator_droop")
                if e:
                    sp.mode = "droop"
                    sp.droop_tau_s = e["parameters"]["tau_s"]
                    mean_d1 = d1_window(cs, r, sig, 0.0, run["t_start"] + run["t_len"])[0] / (run["t_start"] + run["t_len"]) * 60
                    sp.droop_pa_per_nl_min = e["parameters"]["drop_at_mean_bar"] * 1e5 / max(mean_d1, 1.0)
                    e["parameters"]["pa_per_nl_min"] = sp.droop_pa_per_nl_min
                    for d in drives:
                        d.check_valve = True
                cs.edges.append(edges_r)
                specs.append(ph.RunSpec(t_end=run["t_start"] + run["t_len"] + 0.3, supply=sp, drives=drives,
                                        restrictions=restr, p_atm=cs.p_atm, t_amb=cs.t_amb, t_sup=cs.t_sup, bin_s=0.01))
                owners.append((cs, r))
        order = sorted(range(len(specs)), key=lambda k: specs[k].t_end)
        results = [None] * len(specs)
        batch = 400
        for b0 in range(0, len(order), batch):
            ks = order[b0:b0 + batch]
            res = ph.simulate([specs[k] for k in ks], dt=dt)
            for k, rr in zip(ks, res):
                results[k] = rr
            log(f"simulated {min(b0 + batch, len(order))}/{len(order)} runs ({time.time()-t0:.0f} s)")

        # 6. meters, files
        for (cs, r), spec, res in zip(owners, specs, results):
            write_run(cs, r, spec, res, out)
        for cs in cases:
            write_case(cs, out)
        log(f"chunk done ({time.time()-t0:.0f} s)")
        return [cs.idx for cs in cases], time.time() - t0
    finally:
        if not os.environ.get("INDEP_KEEP_WORK"):
            shutil.rmtree(work, ignore_errors=True)


def d1_window(cs, r, sig, t_a, t_b):
    """D1 (+ D2 for nozzles and leaks) of the NOMINAL machine file on the real command edges
    of run r, over machine time [t_a, t_b], NL. Returns (total, per consumer)."""
    p_s = cs.supply_g * 1e5 + cs.atm_file
    per = {}
    for c in cs.drives_doc:
        init, ed = consumer_edges(c, sig)
        lt = tube_lengths(c)
        tot = 0.0
        for t, s in ed:
            if t_a <= t < t_b:
                direction = "extend" if s == 1 else "retract"
                tot += ph.d1_stroke_nl(float(c["bore_mm"]), float(c.get("rod_mm", 0.0)), float(c["stroke_mm"]),
                                       float(c.get("tube_id_mm", 0.0)), lt[0] if s == 1 else lt[1], p_s, cs.t_file,
                                       c["kind"], direction)
        per[c["name"]] = tot
    for c in cs.nozzles_doc + cs.leaks_doc:
        C, b, m = nominal_restriction(c)
        pu = cs.atm_file + float(c["pressure_bar_g"]) * 1e5 if "pressure_bar_g" in c else p_s
        phi, _ = ph.d2_phi(np.array(cs.atm_file / pu), b, m)
        q = C * pu * math.sqrt(ph.T0 / cs.t_file) * float(phi) * 1000.0     # NL/s, D2 + D3
        if c["kind"] == "leak":
            on = t_b - t_a
        else:
            init, ed = consumer_edges(c, sig)
            on, state, last = 0.0, init, 0.0
            for t, s in ed + [(math.inf, None)]:
                if state:
                    on += max(0.0, min(t, t_b) - max(last, t_a))
                state, last = s, t
        per[c["name"]] = q * on
    return sum(per.values()), per


def write_run(cs, r, spec, res, out):
    run = cs.runs[r]
    rng = np.random.default_rng([cs.idx, r, 99])
    meter = dict(cs.meter)
    e = effect(cs, "sensor_lag")
    if e:
        meter["tau_s"] = e["parameters"]["tau_s"]
    e = effect(cs, "meter_gain")
    if e:
        meter["gain"] = e["parameters"]["gain"]
    if effect(cs, "din1343_meter"):
        meter["reference"] = "din1343"
    stamps, flow, sup, true_nl = ph.meter_log(
        res["flow_nl"], res["bin_s"], rng, t_start=run["t_start"], t_len=run["t_len"], rate_hz=meter["rate_hz"],
        tau_s=meter["tau_s"], noise_frac=meter["noise_frac"], gain=meter["gain"], reference=meter["reference"],
        clock_offset=run["clock_offset"], jitter_frac=meter["jitter_frac"], p_supply=res["p_supply"],
        p_atm=cs.p_atm, p_noise_bar=meter["p_noise_bar"])
    d = Path(out) / f"case_{cs.idx:04d}"
    d.mkdir(parents=True, exist_ok=True)
    with open(d / f"run{r+1}.csv", "w") as f:
        f.write("time_s,flow_l_min,supply_bar_g\n")
        for t, q, p in zip(stamps, flow, sup):
            f.write(f"{t:.3f},{q:.3f},{p:.3f}\n")
    # the recorded I/O of the run: the timeline up to a second past the log's end
    t_cut = run["t_start"] + run["t_len"] + 1.0
    with open(cs.timelines[r]) as fi, open(d / f"run{r+1}.timeline.csv", "w") as fo:
        fo.write(next(fi))
        for ln in fi:
            if float(ln.split(",", 1)[0]) <= t_cut:
                fo.write(ln)
    sig = read_timeline(cs.timelines[r])
    d1, per = d1_window(cs, r, sig, run["t_start"], run["t_start"] + run["t_len"])
    per_true = {}
    t_a, t_b = run["t_start"], run["t_start"] + run["t_len"]
    for dd, dspec in zip(res["drives"], spec.drives):
        # the air drawn between a drive's edges, booked to the edges that fall in the window
        ea = dd["edge_air_nl"]
        per_true[dd["name"]] = float(sum(ea[k + 1] for k, (t, _) in enumerate(sorted(dspec.edges)) if t_a <= t < t_b))
    run["restrictions_nl_whole_run"] = {name: float(a) for name, a in res["restr_air_nl"]}
    run["total_nl_true"] = float(true_nl)
    run["measured_nl"] = float(np.sum(flow) / meter["rate_hz"] / 60.0)
    run["d1_nl"] = float(d1)
    run["d1_per_consumer_nl"] = per
    run["physics_per_consumer_nl"] = per_true
    run["real_stroke_s"] = {n: [float(x) for x in s] for n, s in cs.real_st[r].items()}
    run["n_samples"] = int(len(stamps))
    run["supply_bar_g_min_mean_max"] = [float(np.min(sup)), float(np.mean(sup)), float(np.max(sup))]
    run["meter"] = meter


def write_case(cs, out):
    d = Path(out) / f"case_{cs.idx:04d}"
    d.mkdir(parents=True, exist_ok=True)
    prog = cs.path.parent / cs.doc["machine"]["program"]
    shutil.copy(prog, d / prog.name)
    if cs.jittered:
        doc = copy.deepcopy(cs.doc)
        for k, x in enumerate(doc.get("input", [])):
            if k in cs.runs[2]["seeds"]:
                x["seed"] = cs.runs[2]["seeds"][k]      # the nominal file's seeds are run 3's
        (d / "machine.toml").write_text(dump_toml(doc, f"# {cs.machine} (nominal machine file; inputs seeded as run 3)"))
    else:
        shutil.copy(cs.path, d / "machine.toml")
    tot = [r["total_nl_true"] for r in cs.runs]
    d1 = [r["d1_nl"] for r in cs.runs]
    case = {
        "case": cs.idx,
        "machine": cs.machine,
        "category": cs.category,
        "effects": cs.effects,
        "expected_verdicts": cs.expected,
        "perturbation": cs.pert,
        "meter": cs.meter,
        "runs": [{k: v for k, v in r.items() if k != "seeds"} | {"seeds": {str(k): v for k, v in r["seeds"].items()}}
                 for r in cs.runs],
        "inputs_jittered": cs.jittered,
        "total_nl_true": tot,
        "measured_nl": [r["measured_nl"] for r in cs.runs],
        "d1_nl": d1,
        "d1_gap_pct": [100.0 * (a - b) / b for a, b in zip(d1, tot)],
        "notes": "times in machine seconds unless *_logger_s; logger clock = machine time + runs[i].clock_offset; "
                 "d1_gap_pct = (D1 of the nominal file on the real edges - physics) / physics over each log window",
    }
    (d / "case.json").write_text(json.dumps(case, indent=1, default=_json_default))


def _json_default(o):
    if isinstance(o, (np.floating,)):
        return float(o)
    if isinstance(o, (np.integer,)):
        return int(o)
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, tuple):
        return list(o)
    raise TypeError(type(o))


def main(argv=None):
    ap = argparse.ArgumentParser(description="generate independent-physics diagnosis cases")
    ap.add_argument("--out", required=True)
    ap.add_argument("--cases", type=int, default=200)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--machines", default=",".join(MACHINES))
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--dt", type=float, default=1e-3, help="integration step, s (default 1 ms)")
    ap.add_argument("--quiet", action="store_true")
    args = ap.parse_args(argv)
    machines = [m.strip() for m in args.machines.split(",") if m.strip()]
    for m in machines:
        if m not in MACHINES:
            ap.error(f"unknown machine {m!r} (have {', '.join(MACHINES)})")
    rng = np.random.default_rng(args.seed)
    cats = draw_categories(args.cases, rng)
    # machines round-robin within each category, so every category covers every machine
    counter = {}
    machs = []
    for c in cats:
        k = counter.get(c, 0)
        counter[c] = k + 1
        machs.append(machines[(k + args.seed) % len(machines)])
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    ids = list(range(args.cases))
    jobs = max(1, min(args.jobs, args.cases))
    # balance: each worker takes every jobs-th case
    chunks = [(ids[j::jobs], cats[j::jobs], machs[j::jobs], args.seed, str(out), args.dt, args.quiet)
              for j in range(jobs)]
    t0 = time.time()
    if jobs == 1:
        res = [build_chunk(chunks[0])]
    else:
        with mp.get_context("fork").Pool(jobs) as pool:
            res = pool.map(build_chunk, chunks)
    (out / "generate.json").write_text(json.dumps({
        "cases": args.cases, "seed": args.seed, "machines": machines, "jobs": jobs, "dt": args.dt,
        "wall_s": time.time() - t0, "chunk_s": [r[1] for r in res],
        "categories": {c: cats.count(c) for c in dict.fromkeys(cats)}}, indent=1))
    print(f"{args.cases} cases in {out} ({time.time()-t0:.0f} s wall on {jobs} processes)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
