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
from ..lazy import lazy_attributes

# Each name is imported from its module on first use (PEP 562): the plots and the plant
# read a constant or the log reader from here, and must not wait for the fits and scipy's
# optimisers to load.
_LAZY = {"Diagnosis": ".core", "diagnose": ".core", "EFFECTS": ".effects",
         "VOCABULARY": ".effects", "DiagnosisError": ".errors",
         "MeasuredDataError": ".io", "MeasuredRun": ".io", "read_io_timeline": ".io",
         "read_measured": ".io"}

__all__ = ["Diagnosis", "DiagnosisError", "EFFECTS", "MeasuredDataError", "MeasuredRun",
           "VOCABULARY", "diagnose", "read_io_timeline", "read_measured"]


__getattr__, __dir__ = lazy_attributes(__name__, _LAZY)
