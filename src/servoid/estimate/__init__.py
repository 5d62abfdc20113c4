"""Estimators: least squares, ARX and order selection."""

from ._arx import ArxOrders, fit_arx
from ._estimate import Estimate, ParameterRow
from ._ls import LeastSquaresResult, lstsq, solve_gram
from ._order import OrderCandidate, OrderSelection, select_arx_order

__all__ = [
    "ArxOrders",
    "Estimate",
    "LeastSquaresResult",
    "OrderCandidate",
    "OrderSelection",
    "ParameterRow",
    "fit_arx",
    "lstsq",
    "select_arx_order",
    "solve_gram",
]
