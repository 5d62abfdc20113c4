"""Reference data sets shipped with servoid, loaded as Experiments.

:func:`load_emps` — the EMPS electromechanical positioning system (Janot,
Gautier, Brunot, *Data Set and Reference Models of EMPS*, Workshop on
Nonlinear System Identification Benchmarks, 2019): a real ball-screw
axis with friction, recorded in closed loop.
"""

from ._emps import emps_path, load_emps

__all__ = ["emps_path", "load_emps"]
