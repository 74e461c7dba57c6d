"""Unfolding a PLC program into timelines (work in progress: issue 3).

* :mod:`plcpred.sequencer.stdfb` - the IEC 61131-3 standard function blocks
* :mod:`plcpred.sequencer.plant` - cylinder end switches following their valves
"""
