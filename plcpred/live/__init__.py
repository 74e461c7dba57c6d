"""Live: the running machine over OPC UA.

* :func:`watch` - subscribe to a machine's signals and flow meter on its PLC's (or a
  gateway's) OPC UA server, record them as ``diagnose`` reads them and compare them with
  the prediction cycle by cycle (:mod:`~plcpred.live.client`)
* :func:`serve` - the machine's program against the physics plant in (scaled) real time,
  served as an OPC UA server: a digital twin (:mod:`~plcpred.live.server`,
  :class:`Twin`)
* :func:`live_settings` - the machine file's ``[live]`` with its defaults
* :class:`LearnedReference` - the per-consumer factors on D1 learned from the first
  cycles, the reference the alarms judge (:mod:`~plcpred.live.reference`)
* :func:`plot_comparison` - a watch's comparison per cycle as a picture, from its
  events (:mod:`~plcpred.live.plot`; matplotlib is loaded only when it draws)
"""
from .client import Watcher, WatchResult, watch
from .compare import CycleResult, LiveComparison
from .plot import plot_comparison
from .reference import LearnedReference
from .server import ServeResult, serve
from .settings import LiveError, LiveSettings, check_endpoint, live_settings, machine_signals
from .twin import Twin

__all__ = ["CycleResult", "LearnedReference", "LiveComparison", "LiveError", "LiveSettings", "ServeResult",
           "Twin", "WatchResult", "Watcher", "check_endpoint", "live_settings",
           "machine_signals", "plot_comparison", "serve", "watch"]
