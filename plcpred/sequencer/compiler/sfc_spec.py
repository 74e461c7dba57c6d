"""An SFC body as the spec :class:`~plcpred.sequencer.sfc.SfcRuntime` runs: steps,
transitions (each condition a generated function), actions and their qualifiers, and the
step times the executor must schedule."""
from __future__ import annotations

from ...parser import ir
from ...parser.names import ident
from ..types import BOOL, FbT
from .common import COMPARISONS, Scope, error_at
from .conversions import convert
from .flow import children, const_time


class SfcMixin:
    """Part of :class:`~.project.Compiler`: the SFC bodies of FBs and programs."""

    def _sfc_spec(self, fb: FbT, scope: Scope) -> str:
        """Emit the spec of an SFC body as a module-level object; return its name. Its
        lines are emitted after the classes (they refer to methods)."""
        sfc: ir.Sfc = fb.pou.body
        name = f"_sfcspec_{fb.cls_name}"
        out = []
        thresholds: dict[int, list[int]] = {}
        t_read: set[int] = set()
        trans = self._sfc_transitions(fb, scope, out, thresholds, t_read)
        actions, assocs = self._sfc_actions(fb, scope, out)
        lines = list(out)
        made = (f"{name} = _SfcSpec({[s.name for s in sfc.steps]!r}, "
                f"{next(i for i, s in enumerate(sfc.steps) if s.initial)}, "
                f"[{', '.join(trans)}], [], {thresholds!r}, {t_read!r})")
        lines.append((made, None))
        for key, spec in actions.items():
            lines.append((f"_a = {spec}", None))
            lines.append((f"_a.assocs.extend([{', '.join(assocs[key])}])", None))
            lines.append((f"{name}.actions.append(_a)", None))
        self._pending_sfc.extend(lines)
        return name

    def _sfc_transitions(self, fb: FbT, scope: Scope, out: list, thresholds: dict,
                         t_read: set) -> list[str]:
        """The transitions' specs, by priority; their conditions' functions go to
        ``out``."""
        idx = scope.steps
        trans = []
        for k, tr in enumerate(sorted(enumerate(fb.pou.body.transitions),
                                      key=lambda it: (it[1].priority, it[0]))):
            i, tr = tr
            for s in tr.sources + tr.targets:
                if s.upper() not in idx:
                    raise error_at(tr, f"transition refers to unknown step '{s}'")
            self._collect_step_t(tr.condition, scope, thresholds, t_read)
            code, t = self._expr(tr.condition, scope)
            fn = f"_tc_{fb.cls_name}_{i}"
            out.append((f"def {fn}(self):", tr.pos))
            out.append((f"    return {convert(code, t, BOOL, tr.condition)}", tr.pos))
            srcs = tuple(idx[s.upper()] for s in tr.sources)
            tgts = tuple(idx[s.upper()] for s in tr.targets)
            trans.append(f"({srcs!r}, {tgts!r}, {fn}, {tr.priority})")
        return trans

    def _sfc_actions(self, fb: FbT, scope: Scope, out: list) -> tuple[dict, dict]:
        """(action key -> its spec, action key -> its steps' associations); the setters
        of BOOL variables used as actions, and the functions of qualifier times, go to
        ``out``."""
        sfc: ir.Sfc = fb.pou.body
        body_actions = {ident(a.name): a for a in sfc.actions}
        body_actions.update({ident(a.name): a for a in fb.pou.actions})
        actions: dict[str, str] = {}
        assocs: dict[str, list[str]] = {}
        for si, step in enumerate(sfc.steps):
            for assoc in step.actions:
                key = ident(assoc.action)
                if key not in actions:
                    if key in body_actions:
                        actions[key] = (f"_ActionSpec({assoc.action!r}, "
                                        f"body={fb.cls_name}.a_{key})")
                    elif key in scope.names and scope.names[key][1] == BOOL:
                        setter = f"_set_{fb.cls_name}_{key}"
                        code = scope.names[key][0].replace("self.", "o.", 1)
                        out.append((f"def {setter}(o, v):", assoc.pos))
                        out.append((f"    {code} = v", assoc.pos))
                        actions[key] = f"_ActionSpec({assoc.action!r}, setter={setter})"
                    else:
                        raise error_at(assoc, f"step {step.name}: '{assoc.action}' is "
                                              "neither an action nor a BOOL variable")
                    assocs[key] = []
                assocs[key].append(f"({si}, {self._qualifier(fb, scope, assoc, out)})")
        return actions, assocs

    def _qualifier(self, fb: FbT, scope: Scope, assoc: ir.ActionAssoc, out: list) -> str:
        """``'Q', time function`` of an action association; the function of a timed
        qualifier's time goes to ``out``."""
        q = assoc.qualifier.upper()
        if q in ("L", "D", "SD", "DS", "SL"):
            if assoc.time is None:
                raise error_at(assoc, f"qualifier {q} needs a time")
            code, _ = self._expr(assoc.time, scope)
            tfn = f"_at_{fb.cls_name}_{len(out)}"
            out.append((f"def {tfn}(self):", assoc.pos))
            out.append((f"    return {code}", assoc.pos))
        else:
            tfn = "None"
        return f"{q!r}, {tfn}"

    def _collect_step_t(self, e, scope, thresholds, t_read):
        """Constant ``step.T`` comparisons become scheduled events; anything else that
        reads ``step.T`` makes the executor step every scan while the step is active."""
        if isinstance(e, ir.Binary) and e.op in COMPARISONS:
            for a, b in ((e.left, e.right), (e.right, e.left)):
                si = self._step_member(a, scope, "T")
                if si is not None:
                    c = const_time(b)
                    if c is None:
                        t_read.add(si)
                    else:
                        thresholds.setdefault(si, []).append(c)
                    self._collect_step_t(b, scope, thresholds, t_read)
                    return
        si = self._step_member(e, scope, "T")
        if si is not None:
            t_read.add(si)
            return
        for child in children(e):
            self._collect_step_t(child, scope, thresholds, t_read)

    @staticmethod
    def _step_member(e, scope, member):
        """The index of the step ``e`` names ``member`` of (``Step3.T``), or None."""
        if (isinstance(e, ir.Member) and ident(e.member) == member
                and isinstance(e.base, ir.Name) and ident(e.base.name) in scope.steps):
            return scope.steps[ident(e.base.name)]
        return None
