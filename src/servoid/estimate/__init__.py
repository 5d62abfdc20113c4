"""Estimators: least squares, ARX and order selection."""

from ._arx import ArxOrders, fit_arx
from ._band import FrequencyBand, frequency_band
from ._estimate import Estimate, ParameterRow
from ._greybox import GreyboxModel, GreyboxParameter, fit_greybox
from ._inverse import (
    FRICTION_MODELS,
    InverseDynamicsRegression,
    fit_closed_loop_oe,
    fit_inverse_dynamics,
    inverse_dynamics_regression,
)
from ._ls import LeastSquaresResult, lstsq, solve_gram
from ._order import OrderCandidate, OrderSelection, select_arx_order
from ._rls import RecursiveLeastSquaresResult, fit_rls
from ._separable import fit_separable
from ._svf import FilteredSignal, filter_product, state_variable_filter
from ._tf_greybox import fit_tf_greybox

__all__ = [
    "FRICTION_MODELS",
    "ArxOrders",
    "Estimate",
    "FilteredSignal",
    "FrequencyBand",
    "GreyboxModel",
    "GreyboxParameter",
    "InverseDynamicsRegression",
    "LeastSquaresResult",
    "OrderCandidate",
    "OrderSelection",
    "ParameterRow",
    "RecursiveLeastSquaresResult",
    "filter_product",
    "fit_arx",
    "fit_closed_loop_oe",
    "fit_greybox",
    "fit_inverse_dynamics",
    "fit_rls",
    "fit_separable",
    "fit_tf_greybox",
    "frequency_band",
    "inverse_dynamics_regression",
    "lstsq",
    "select_arx_order",
    "solve_gram",
    "state_variable_filter",
]
