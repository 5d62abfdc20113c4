"""Virtual test benches: the parts every actuator's bench is built from.

:func:`simulate_lti` and :func:`simulate_lti_loop` run a continuous linear
plant (or a loop) far above the sample rate with an anti-alias filter and
decimation, as a rig samples it; the analog filters and the converter
models the actuators' benches share are here too.  Each actuator's own
bench lives with it in :mod:`servoid.plants` (``servoid.plants.ehsa``:
:class:`~servoid.plants.ehsa.EhsaBench`, ``run``, ``write_bench_files``,
``write_virtual_fleet``; ``servoid.plants.pneumatic``:
``write_pneumatic_campaign``; ``servoid.plants.ema``); their names are still
found here for one release, with a :class:`DeprecationWarning`.
"""

from .._moved import moved_names
from ._lti import Intersample, simulate_lti, simulate_lti_loop

# isort: split
# Building blocks other servoid packages import (through this package, not its modules);
# not part of the public API (__all__).
from ._analog import Hold as Hold
from ._analog import butterworth as butterworth
from ._analog import discrete_sos as discrete_sos
from ._analog import discretise as discretise
from ._analog import realise as realise
from ._daq import note_warning as note_warning
from ._daq import quantise as quantise
from ._daq import resolve_rng as resolve_rng

__all__ = [
    "Intersample",
    "simulate_lti",
    "simulate_lti_loop",
]

#: Names that moved into servoid.plants: found there, with a warning, for one release.
_MOVED = {
    "BenchRun": "servoid.plants.ehsa",
    "CHANNELS": "servoid.plants.ehsa",
    "EhsaBench": "servoid.plants.ehsa",
    "EhsaTruth": "servoid.plants.ehsa",
    "FIDELITIES": "servoid.plants.ehsa",
    "FLEET_LIMITS": "servoid.plants.ehsa",
    "FLEET_SCATTER": "servoid.plants.ehsa",
    "Fidelity": "servoid.plants.ehsa",
    "PNEUMATIC_CHANNELS": "servoid.plants.pneumatic",
    "PNEUMATIC_TESTS": "servoid.plants.pneumatic",
    "PneumaticBench": "servoid.plants.pneumatic",
    "PneumaticRun": "servoid.plants.pneumatic",
    "PneumaticTest": "servoid.plants.pneumatic",
    "PneumaticTestName": "servoid.plants.pneumatic",
    "REFERENCES": "servoid.plants.ehsa",
    "Reference": "servoid.plants.ehsa",
    "RigFormat": "servoid.plants.ehsa",
    "VirtualFleet": "servoid.plants.ehsa",
    "digitize": "servoid.plants.ehsa",
    "experiment_document": "servoid.plants.ehsa",
    "pneumatic_experiment_document": "servoid.plants.pneumatic",
    "pneumatic_truth_document": "servoid.plants.pneumatic",
    "run": "servoid.plants.ehsa",
    "run_pneumatic": "servoid.plants.pneumatic",
    "truth_document": "servoid.plants.ehsa",
    "write_bench_files": "servoid.plants.ehsa",
    "write_pneumatic_campaign": "servoid.plants.pneumatic",
    "write_virtual_fleet": "servoid.plants.ehsa",
}
__getattr__ = moved_names(__name__, _MOVED)
