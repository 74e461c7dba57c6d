"""A physics virtual plant: the machine as it really behaves, for ``plcpred emulate``,
for testing the diagnosis on data with effects the activation model leaves out, and as
the diagnosis' reference of what a healthy machine draws.

The drives' own physics (chambers, friction, one supply's group integrated between
events, stroke times) is in :mod:`plcpred.physics`; this package runs a whole machine.

* :mod:`~plcpred.plant.model` - the machine as groups, and the sequencer's adapters
* :mod:`~plcpred.plant.flow_meter` - what a flow meter reports
* :mod:`~plcpred.plant.truth` - truth files (the real machine's deviations)
* :mod:`~plcpred.plant.replay` - the plant switched by given edges (open loop), or run
  against the program without a meter: the diagnosis' reference of the nominal machine
* :func:`emulate` - closed-loop run, meter log and true flows
"""
from .emulate import Emulation, emulate
from .truth import load_real_machine, merge_truth

__all__ = ["Emulation", "emulate", "load_real_machine", "merge_truth"]
