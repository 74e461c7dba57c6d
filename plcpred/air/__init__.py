"""Air demand from timelines: the activation/transition consumption model.

The flows (D2/D3) and volumes (D1) it uses are in :mod:`plcpred.physics`.

* :mod:`~plcpred.air.demand` - edges to a :class:`DemandProfile` on a time grid
* :func:`predict` - machine file to timeline, demand profile and files
* :func:`~plcpred.air.sizing.size` - compressor and receiver sizing of a profile
* :func:`~plcpred.air.compare.compare` - two predictions against an allowed increase
"""
from .demand import ConsumerModel, DemandProfile, activation_matrix, consumer_models, demand_profile
from .predict import Prediction, default_dt, predict

__all__ = ["ConsumerModel", "DemandProfile", "Prediction", "activation_matrix",
           "consumer_models", "default_dt", "demand_profile", "predict"]
