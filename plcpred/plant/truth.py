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

from ..machine import (
    MachineError,
    error_place,
    locate_error,
    machine_from_data,
    read_machine_data,
    unknown_name,
)

_LISTS = {"consumer": "name", "input": "signal", "line": "name"}
_TABLES = ("machine", "signals", "meter")


def merge_truth(nominal: dict, truth: dict, truth_file: str) -> dict:
    """The nominal machine data with the truth file's deviations applied."""
    out = copy.deepcopy(nominal)
    unknown = [k for k in truth if k not in _LISTS and k not in _TABLES]
    if unknown:
        raise MachineError(truth_file, "", unknown_name("table", unknown[0],
                                                        (*_TABLES, *_LISTS))
                           + " (a truth file holds [machine], [signals], [meter], "
                             "[[consumer]], [[input]], [[line]])", table=unknown[0])
    for key in _TABLES:
        if key in truth:
            if not isinstance(truth[key], dict):
                raise MachineError(truth_file, f"[{key}]", "must be a table", table=key)
            out.setdefault(key, {}).update(truth[key])
    for key, ident in _LISTS.items():
        if key not in truth:
            continue
        if not isinstance(truth[key], list):
            raise MachineError(truth_file, f"[[{key}]]", f"write it as [[{key}]]", table=key)
        existing = out.setdefault(key, [])
        for i, table in enumerate(truth[key]):
            if not isinstance(table, dict) or not isinstance(table.get(ident), str):
                raise MachineError(truth_file, f"[[{key}]] #{i + 1}",
                                   f"needs a '{ident}' (to match or add a {key})",
                                   table=key, index=i)
            for old in existing:
                if isinstance(old, dict) and old.get(ident) == table[ident]:
                    old.update(table)
                    break
            else:
                if key == "consumer" and "kind" not in table:
                    # a new consumer needs its kind: without one, this was meant to change
                    # one the machine has (a name mistyped)
                    raise MachineError(truth_file, f"[[{key}]] #{i + 1}",
                                       _no_consumer(table[ident], existing),
                                       table=key, index=i, key=ident)
                existing.append(dict(table))
    return out


def _no_consumer(name: str, existing: list) -> str:
    names = sorted(o["name"] for o in existing if isinstance(o, dict)
                   and isinstance(o.get("name"), str))
    near = difflib.get_close_matches(name, names, n=1, cutoff=0.6)
    return (f"no consumer '{name}' in the machine file"
            + (f"; did you mean '{near[0]}'?" if near else
               f" (its consumers: {', '.join(names) or 'none'})")
            + " (a consumer to add needs its kind)")


def load_real_machine(nominal_path, truth_path=None):
    """The machine as it really is: the nominal file with a truth file applied. An error
    in the merged machine points at the truth file's line when the key that is wrong
    came from it, else at the nominal file's."""
    nominal_path = Path(nominal_path)
    data = read_machine_data(nominal_path)
    if truth_path is None:
        return machine_from_data(data, nominal_path)
    truth = read_machine_data(truth_path)
    try:
        merged = merge_truth(data, truth, str(truth_path))
    except MachineError as e:
        raise locate_error(e, truth_path, truth)
    try:
        return machine_from_data(merged, nominal_path)
    except MachineError as e:
        raise _located_in_either(e, merged, (nominal_path, data), (Path(truth_path), truth)) \
            from None


def _located_in_either(e: MachineError, merged: dict, nominal: tuple, truth: tuple):
    """``e`` (raised on the merged data) at the truth file's line of its key when the
    truth file gives that key (or adds the table), else at the nominal file's."""
    (nominal_path, nominal_data), (truth_path, truth_data) = nominal, truth
    table, index, key = error_place(e, merged)
    in_truth, truth_index = False, None
    if table in _LISTS and index is not None and isinstance(merged.get(table), list):
        ident = _LISTS[table]
        name = merged[table][index].get(ident) if index < len(merged[table]) else None
        truth_index = next((i for i, t in enumerate(truth_data.get(table) or [])
                            if isinstance(t, dict) and t.get(ident) == name), None)
        added = not any(isinstance(t, dict) and t.get(ident) == name
                        for t in nominal_data.get(table) or [])
        in_truth = truth_index is not None and (
            added or key in truth_data[table][truth_index])
    elif table in _TABLES and isinstance(truth_data.get(table), dict):
        in_truth = key in truth_data[table] or table not in nominal_data
    if in_truth:
        placed = MachineError(str(truth_path), e.where, e.message, table=table,
                              index=truth_index, key=key)
        return locate_error(placed, truth_path, truth_data)
    placed = MachineError(str(nominal_path), e.where,
                          f"{e.message} (with the deviations of {truth_path})", table=table,
                          index=index, key=key)
    return locate_error(placed, nominal_path, nominal_data)
