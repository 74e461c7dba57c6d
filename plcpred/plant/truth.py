"""Truth files: the real machine's deviations from its nominal machine file.

A truth file is a partial machine file. Its ``[machine]``, ``[signals]`` and ``[meter]``
keys override the nominal ones; a ``[[consumer]]``, ``[[input]]`` or ``[[line]]`` whose
name (signal, for inputs) is new is added (a hidden leak), one whose name exists has only
the keys it gives overridden (a longer tube, a throttled exhaust). The predictor and the
diagnosis see only the nominal file; ``emulate --truth`` runs the real one.
"""
from __future__ import annotations

import copy
import difflib
from pathlib import Path

from ..machine import MachineError, machine_from_data, read_machine_data

_LISTS = {"consumer": "name", "input": "signal", "line": "name"}
_TABLES = ("machine", "signals", "meter")


def merge_truth(nominal: dict, truth: dict, truth_file: str) -> dict:
    """The nominal machine data with the truth file's deviations applied."""
    out = copy.deepcopy(nominal)
    unknown = sorted(set(truth) - set(_LISTS) - set(_TABLES))
    if unknown:
        raise MachineError(truth_file, "", f"unknown table [{unknown[0]}] (a truth file "
                           "holds [machine], [signals], [meter], [[consumer]], [[input]], "
                           "[[line]])")
    for key in _TABLES:
        if key in truth:
            if not isinstance(truth[key], dict):
                raise MachineError(truth_file, f"[{key}]", "must be a table")
            out.setdefault(key, {}).update(truth[key])
    for key, ident in _LISTS.items():
        if key not in truth:
            continue
        if not isinstance(truth[key], list):
            raise MachineError(truth_file, f"[[{key}]]", f"write it as [[{key}]]")
        existing = out.setdefault(key, [])
        for i, table in enumerate(truth[key]):
            if not isinstance(table, dict) or not isinstance(table.get(ident), str):
                raise MachineError(truth_file, f"[[{key}]] #{i + 1}",
                                   f"needs a '{ident}' (to match or add a {key})")
            for old in existing:
                if isinstance(old, dict) and old.get(ident) == table[ident]:
                    old.update(table)
                    break
            else:
                if key == "consumer" and "kind" not in table:
                    # a new consumer needs its kind: without one, this was meant to change
                    # one the machine has (a name mistyped)
                    names = [o.get(ident) for o in existing if isinstance(o, dict)]
                    near = difflib.get_close_matches(table[ident], [n for n in names
                                                                    if isinstance(n, str)],
                                                     n=1, cutoff=0.6)
                    raise MachineError(truth_file, f"[[{key}]] #{i + 1}",
                                       f"no consumer '{table[ident]}' in the machine file to "
                                       "change" + (f" (did you mean '{near[0]}'?)" if near
                                                   else "")
                                       + "; a consumer to add needs its kind")
                existing.append(dict(table))
    return out


def load_real_machine(nominal_path, truth_path=None):
    """The machine as it really is: the nominal file with a truth file applied. Errors in
    the merged file name the truth file (where the deviation came from) and the nominal
    one."""
    nominal_path = Path(nominal_path)
    data = read_machine_data(nominal_path)
    if truth_path is None:
        return machine_from_data(data, nominal_path)
    truth = read_machine_data(truth_path)
    merged = merge_truth(data, truth, str(truth_path))
    try:
        return machine_from_data(merged, nominal_path)
    except MachineError as e:
        raise MachineError(f"{truth_path} (applied to {nominal_path})", e.where,
                           e.message) from None
