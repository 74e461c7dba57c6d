"""A physics virtual plant: the machine as it really behaves, for ``plcpred emulate``,
for testing the diagnosis on data with effects the activation model leaves out, and for
stroke times from physics (``stroke_time_s = "auto"``), and as the diagnosis' reference
of what a healthy machine draws.

* :mod:`~plcpred.plant.physics` - D2 flows, D4 chambers, Stribeck friction (plain functions)
* :mod:`~plcpred.plant.drive` - a drive's parameters and their documented defaults
* :mod:`~plcpred.plant.group` - drives on one supply, integrated between discrete events
* :mod:`~plcpred.plant.model` - the machine as groups, and the sequencer's adapters
* :mod:`~plcpred.plant.strokes` - stroke times from physics; flow controls set to a time
* :mod:`~plcpred.plant.meter` - what a flow meter reports
* :mod:`~plcpred.plant.truth` - truth files (the real machine's deviations)
* :mod:`~plcpred.plant.replay` - the plant switched by given edges (open loop), or run
  against the program without a meter: the diagnosis' reference of the nominal machine
* :func:`emulate` - closed-loop run, meter log and true flows
"""
from .emulate import Emulation, emulate
from .truth import load_real_machine, merge_truth

__all__ = ["Emulation", "emulate", "load_real_machine", "merge_truth"]
