"""Virtual test benches: an actuator in its loop, sensors and a DAQ.

Rehearse a test before running it: :class:`EhsaBench` describes the rig
(EHSA parameters and model fidelity, acquisition rate, analog anti-alias
filter, converter bits and range, transducers, sensor noise as an SNR of
the data identification sees), :func:`run` plays a designed excitation on
it and returns the raw record in volts with the truth
(:class:`BenchRun`, :class:`EhsaTruth`), and :func:`write_bench_files`
writes what a real rig writes: the TDMS or CSV file, the experiment TOML
that calibrates and decimates it, and ``truth.json``.

Example::

    from servoid.bench import EhsaBench, run, write_bench_files
    from servoid.signals import prbs

    ex = prbs(11, clock=10, amplitude=1e-3, dt=1e-3)
    rec = run(EhsaBench(fidelity="nonlinear", snr_db=30.0), ex, rng=7)
    write_bench_files(rec, "rehearsal")
"""

from ._config import FIDELITIES, REFERENCES, EhsaBench, Fidelity, Reference
from ._files import RigFormat, experiment_document, truth_document, write_bench_files
from ._fleet import FLEET_LIMITS, FLEET_SCATTER, VirtualFleet, write_virtual_fleet
from ._lti import Intersample, simulate_lti, simulate_lti_loop
from ._pneumatic import (
    PNEUMATIC_CHANNELS,
    PNEUMATIC_TESTS,
    PneumaticBench,
    PneumaticRun,
    PneumaticTest,
    PneumaticTestName,
    run_pneumatic,
)
from ._pneumatic_files import (
    pneumatic_experiment_document,
    pneumatic_truth_document,
    write_pneumatic_campaign,
)
from ._run import CHANNELS, BenchRun, EhsaTruth, digitize, run

__all__ = [
    "CHANNELS",
    "FIDELITIES",
    "FLEET_LIMITS",
    "FLEET_SCATTER",
    "PNEUMATIC_CHANNELS",
    "PNEUMATIC_TESTS",
    "REFERENCES",
    "BenchRun",
    "EhsaBench",
    "EhsaTruth",
    "Fidelity",
    "Intersample",
    "PneumaticBench",
    "PneumaticRun",
    "PneumaticTest",
    "PneumaticTestName",
    "Reference",
    "RigFormat",
    "VirtualFleet",
    "digitize",
    "experiment_document",
    "pneumatic_experiment_document",
    "pneumatic_truth_document",
    "run",
    "run_pneumatic",
    "simulate_lti",
    "simulate_lti_loop",
    "truth_document",
    "write_bench_files",
    "write_pneumatic_campaign",
    "write_virtual_fleet",
]
