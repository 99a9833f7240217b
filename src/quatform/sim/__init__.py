"""Sim layer: plants, measurement models, the one closed loop and its log, metrics
(above references and control, below scenarios).

* :func:`simulate` - the one loop (any plant, any measurement model, B worlds per tick);
* :class:`Log`, :class:`Channel` - what it returns, read by metrics, writers and figures;
* :mod:`.plants` - the plants; :mod:`.measurement` - the measurement models;
* :mod:`.output` - atomic files and staged run folders (the writers are the report layer's).
"""

from .log import Channel, Log
from .metrics import compute_metrics, errors_from_robots
from .simulate import PerfectMeasurement, simulate

__all__ = ["simulate", "PerfectMeasurement", "Log", "Channel", "compute_metrics", "errors_from_robots"]
