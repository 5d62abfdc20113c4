"""LTI models: polynomial (ARX … BJ), transfer functions and state space.

Continuous models have ``dt=None``; discrete ones have ``dt`` [s] and
remember how they were discretised (``method``, ``prewarp``).  :func:`c2d`
and :func:`d2c` convert both ways (ZOH, FOH, Tustin); :func:`to_scipy`,
:func:`from_scipy`, :func:`to_control` and :func:`from_control` talk to
scipy.signal and python-control; :func:`save_model` and :func:`load_model`
keep a model in a JSON file, :func:`export_mat` hands it to MATLAB.  :class:`FrequencyResponseData` is a
measured (nonparametric) frequency response; :func:`bandwidth`,
:func:`phase_lag` and :func:`resonance_peak` give the spec numbers of it
or of any model.  :func:`bode`, :func:`freqresp` and :func:`simulate` take
any model — polynomial, transfer function, state space, an Estimate of one,
or a python-control / scipy.signal system (:func:`as_lti`).
"""

from typing import Any

from ._discretize import c2d, d2c
from ._file import export_mat, load_model, save_model
from ._frd import FrequencyResponseData, NonlinearDistortion
from ._generic import as_lti, bode, freqresp, simulate
from ._interop import from_control, from_scipy, to_control, to_scipy
from ._polynomial import PolynomialModel
from ._response import TimeResponse
from ._specs import ResonancePeak, bandwidth, phase_lag, resonance_peak
from ._statespace import StateSpace
from ._transfer import TransferFunction

# isort: split
# Building blocks other servoid packages import (through this package, not its modules);
# not part of the public API (__all__).
from ._file import RECORD_TYPES as RECORD_TYPES
from ._file import model_from_record as model_from_record
from ._file import model_record as model_record
from ._file import past_float as past_float
from ._file import record_text as record_text
from ._file import write_mat as write_mat

__all__ = [
    "FrequencyResponseData",
    "NonlinearDistortion",
    "PolynomialModel",
    "ResonancePeak",
    "StateSpace",
    "TimeResponse",
    "TransferFunction",
    "as_lti",
    "bandwidth",
    "bode",
    "c2d",
    "d2c",
    "export_mat",
    "freqresp",
    "from_control",
    "from_scipy",
    "load_model",
    "phase_lag",
    "resonance_peak",
    "save_model",
    "simulate",
    "to_control",
    "to_scipy",
]


def __getattr__(name: str) -> Any:
    """The compiled kernels other packages share, imported on first use (numba)."""
    if name in ("all_finite", "filter_into"):
        from . import _kernels

        return getattr(_kernels, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
