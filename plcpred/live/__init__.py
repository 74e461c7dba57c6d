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
"""
from .client import Watcher, WatchResult, watch
from .compare import CycleResult, LiveComparison
from .reference import LearnedReference
from .server import ServeResult, serve
from .settings import LiveError, LiveSettings, check_endpoint, live_settings, machine_signals
from .twin import Twin

__all__ = ["CycleResult", "LearnedReference", "LiveComparison", "LiveError", "LiveSettings", "ServeResult",
           "Twin", "WatchResult", "Watcher", "check_endpoint", "live_settings",
           "machine_signals", "serve", "watch"]
