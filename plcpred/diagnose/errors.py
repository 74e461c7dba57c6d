"""The diagnosis' own error: measured data that cannot be compared with a prediction.
(A file that cannot be read at all is a :class:`~plcpred.diagnose.io.MeasuredDataError`.)"""
from __future__ import annotations

from ..errors import PlcpredError


class DiagnosisError(PlcpredError):
    """Measured data that cannot be compared with the machine's prediction."""
