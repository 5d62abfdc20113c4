"""Fleets: identify every record of a production batch or a life test, on Dask or serially.

``servoid fleet FLEET.toml`` (and :func:`run_fleet`) runs the registered
identification of every record a fleet file names — each record as a Dask
task, checkpointed as it finishes and skipped on a re-run when its inputs
and options are unchanged — and writes one table (``fleet.csv``,
``fleet.parquet``), a summary (``fleet.json``) and a report with
acceptance limits, trends, control limits, drift and outliers.  The
local Dask cluster is private to its user (TLS on 127.0.0.1 with
credentials made for the run); a scheduler given by address is used only
with the security the user gives (:func:`tls_security`).

>>> from servoid.fleet import run_fleet                      # doctest: +SKIP
>>> result = run_fleet("batch.toml", workers=1)              # doctest: +SKIP
>>> result.failing_units                                     # doctest: +SKIP
('SN-0107',)
"""

from ..workflows import ParameterValue, RecordSummary, summarise
from ._cluster import tls_security
from ._limits import RULE, Limit
from ._result import FleetResult, ParameterStats
from ._run import run_fleet
from ._spec import FleetRecord, FleetSpec, load_fleet_spec
from ._stats import ControlLimits, Drift, control_limits, drift, robust_z

__all__ = [
    "RULE",
    "ControlLimits",
    "Drift",
    "FleetRecord",
    "FleetResult",
    "FleetSpec",
    "Limit",
    "ParameterStats",
    "ParameterValue",
    "RecordSummary",
    "control_limits",
    "drift",
    "load_fleet_spec",
    "robust_z",
    "run_fleet",
    "summarise",
    "tls_security",
]
