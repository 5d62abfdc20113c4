"""Reference data sets shipped with servoid, loaded as Experiments.

:func:`load_emps` — the EMPS electromechanical positioning system (Janot,
Gautier, Brunot, *Data Set and Reference Models of EMPS*, Workshop on
Nonlinear System Identification Benchmarks, 2019): a real ball-screw
axis with friction, recorded in closed loop.

:func:`load_daisy` — three real records of the DaISy database (De Moor
et al., 1997): a flexible robot arm and a hair dryer (open loop), a ball
and beam (closed loop, controller unknown).

:func:`load_wiener_hammerstein` — the Wiener–Hammerstein benchmark
(Schoukens, Suykens, Ljung, SYSID 2009): a real filter–diode–filter
circuit at 51.2 kHz, its estimation and test parts.
"""

from ._daisy import DAISY_RECORDS, DaisyRecord, daisy_path, load_daisy
from ._emps import emps_path, load_emps
from ._wiener_hammerstein import (
    WH_CITATION,
    WH_PARTS,
    load_wiener_hammerstein,
    wiener_hammerstein_path,
)

__all__ = ["DAISY_RECORDS", "WH_CITATION", "WH_PARTS", "DaisyRecord", "daisy_path", "emps_path",
           "load_daisy", "load_emps", "load_wiener_hammerstein", "wiener_hammerstein_path"]
