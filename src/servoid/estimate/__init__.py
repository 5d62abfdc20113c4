"""Estimators: least squares, ARX, prediction error, IV, subspace, continuous time, FRF."""

from ._arx import ArxOrders, fit_arx
from ._band import FrequencyBand, frequency_band
from ._diagnostics import (
    Identifiability,
    IdentifiabilityFlag,
    MultistartSummary,
    check_identifiability,
)
from ._estimate import Estimate, ParameterRow
from ._fit_frf import FrfWeighting, fit_frf
from ._frf import FrfMethod, estimate_frf
from ._greybox import GreyboxModel, GreyboxParameter, fit_greybox
from ._innovation import InnovationModel
from ._inverse import (
    FRICTION_MODELS,
    InverseDynamicsRegression,
    fit_closed_loop_oe,
    fit_inverse_dynamics,
    inverse_dynamics_regression,
)
from ._iv import fit_iv
from ._ls import LeastSquaresResult, lstsq, solve_gram
from ._modal import modal_parameters
from ._order import OrderCandidate, OrderSelection, select_arx_order
from ._pem import fit_armax, fit_bj, fit_oe, fit_pem
from ._rls import RecursiveLeastSquaresResult, fit_rls
from ._search import StructureCandidate, StructureSelection, select_order
from ._separable import fit_separable
from ._srivc import fit_tf
from ._ss_polynomial import to_polynomial
from ._subspace import fit_n4sid
from ._svf import FilteredSignal, filter_product, state_variable_filter
from ._tf_greybox import fit_tf_greybox

__all__ = [
    "FRICTION_MODELS",
    "ArxOrders",
    "Estimate",
    "FilteredSignal",
    "FrequencyBand",
    "FrfMethod",
    "FrfWeighting",
    "GreyboxModel",
    "GreyboxParameter",
    "Identifiability",
    "IdentifiabilityFlag",
    "InnovationModel",
    "InverseDynamicsRegression",
    "LeastSquaresResult",
    "MultistartSummary",
    "OrderCandidate",
    "OrderSelection",
    "ParameterRow",
    "RecursiveLeastSquaresResult",
    "StructureCandidate",
    "StructureSelection",
    "check_identifiability",
    "estimate_frf",
    "filter_product",
    "fit_armax",
    "fit_arx",
    "fit_bj",
    "fit_closed_loop_oe",
    "fit_frf",
    "fit_greybox",
    "fit_inverse_dynamics",
    "fit_iv",
    "fit_n4sid",
    "fit_oe",
    "fit_pem",
    "fit_rls",
    "fit_separable",
    "fit_tf",
    "fit_tf_greybox",
    "frequency_band",
    "inverse_dynamics_regression",
    "lstsq",
    "modal_parameters",
    "select_arx_order",
    "select_order",
    "solve_gram",
    "state_variable_filter",
    "to_polynomial",
]
