"""The sim-to-real gap: where a measured run departs from the prediction, which
unmodelled effect causes it, and how far the gap shrinks once that effect is in the model,
on samples the fit never saw.

* :func:`read_measured` - a flow log (any logger's CSV, units, reference condition)
* :func:`read_io_timeline` - a recorded I/O trace in ``timeline.csv`` form
* :func:`diagnose` - the whole diagnosis, a :class:`Diagnosis` with ``summary()`` (JSON)
  and ``report()`` (text)
* :data:`EFFECTS` - the vocabulary of effects, each a bounded change of the activation
  model (:mod:`~plcpred.diagnose.effects`)
"""
from .core import Diagnosis, diagnose
from .effects import EFFECTS, VOCABULARY
from .errors import DiagnosisError
from .io import MeasuredDataError, MeasuredRun, read_io_timeline, read_measured

__all__ = ["Diagnosis", "DiagnosisError", "EFFECTS", "MeasuredDataError", "MeasuredRun",
           "VOCABULARY", "diagnose", "read_io_timeline", "read_measured"]
