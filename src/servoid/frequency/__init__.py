"""Frequency-domain identification: nonparametric FRFs with variances, ML fits, acceptance.

The nonparametric estimators return an :class:`FrfMeasurement`: the
response on its lines with its noise variance (and, for M random-phase
realisations, the stochastic nonlinear variance), the degrees of freedom
of those estimates and the distortion levels of the detection lines.

- :func:`estimate_lpm`, :func:`estimate_lrm`: local polynomial / rational
  method for any excitation, transients included (open or closed loop).
- :func:`estimate_bla`: periodic excitation, M realisations × P periods:
  the best linear approximation with noise and nonlinear variances, odd
  and even distortion levels; closed loop from the reference.

:func:`fit_ml` fits an s- or z-domain transfer function to a measurement
by (sample) maximum likelihood, with the parameter covariance and the
cost-function test; :func:`select_ml_order` picks the simplest order
that passes it.  :func:`acceptance_numbers` reads bandwidth, phase lag,
resonance and DC gain from the fitted model with 95 % intervals, and
:func:`judge` applies limits under the fleet's rule (pass only when the
interval lies inside).
"""

from ._acceptance import (
    LIMIT_KEYS,
    RULE,
    AcceptanceCheck,
    SpecNumber,
    acceptance_numbers,
    judge,
)
from ._bla import estimate_bla
from ._local import estimate_lpm, estimate_lrm
from ._measured import DistortionLevels, FrfMeasurement, VarianceKind
from ._ml import Domain, MlFit, MlStart, fit_ml, select_ml_order

__all__ = [
    "LIMIT_KEYS",
    "RULE",
    "AcceptanceCheck",
    "DistortionLevels",
    "Domain",
    "FrfMeasurement",
    "MlFit",
    "MlStart",
    "SpecNumber",
    "VarianceKind",
    "acceptance_numbers",
    "estimate_bla",
    "estimate_lpm",
    "estimate_lrm",
    "fit_ml",
    "judge",
    "select_ml_order",
]
