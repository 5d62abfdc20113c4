"""Estimators: least squares, ARX and order selection."""

from ._arx import ArxOrders, fit_arx
from ._estimate import Estimate, ParameterRow
from ._ls import LeastSquaresResult, lstsq, solve_gram
from ._order import OrderCandidate, OrderSelection, select_arx_order
from ._rls import RecursiveLeastSquaresResult, fit_rls
from ._svf import FilteredSignal, filter_product, state_variable_filter
from ._tf_greybox import fit_tf_greybox

__all__ = [
    "ArxOrders",
    "Estimate",
    "FilteredSignal",
    "LeastSquaresResult",
    "OrderCandidate",
    "OrderSelection",
    "ParameterRow",
    "RecursiveLeastSquaresResult",
    "filter_product",
    "fit_arx",
    "fit_rls",
    "fit_tf_greybox",
    "lstsq",
    "select_arx_order",
    "solve_gram",
    "state_variable_filter",
]
