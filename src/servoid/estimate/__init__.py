"""Estimators: least squares, ARX, prediction error, IV, subspace, continuous time, FRF.

The estimators load on first use (PEP 562), so that ``import servoid.estimate``
does not import numba, scipy and every estimator's module before one is
called: ``from servoid.estimate import fit_arx`` imports ``_arx`` and what
it needs, nothing else.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .._exports import lazy_exports
from .._moved import moved_names

if TYPE_CHECKING:
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
    from ._iv import fit_iv
    from ._ls import LeastSquaresResult, lstsq, solve_gram
    from ._modal import ModalParameters, modal_parameters
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

#: Exported name → the private module that defines it.
_WHERE = {
    "ArxOrders": "_arx",
    "Estimate": "_estimate",
    "FilteredSignal": "_svf",
    "FrequencyBand": "_band",
    "FrfMethod": "_frf",
    "FrfWeighting": "_fit_frf",
    "GreyboxModel": "_greybox",
    "GreyboxParameter": "_greybox",
    "Identifiability": "_diagnostics",
    "IdentifiabilityFlag": "_diagnostics",
    "InnovationModel": "_innovation",
    "LeastSquaresResult": "_ls",
    "ModalParameters": "_modal",
    "MultistartSummary": "_diagnostics",
    "OrderCandidate": "_order",
    "OrderSelection": "_order",
    "ParameterRow": "_estimate",
    "RecursiveLeastSquaresResult": "_rls",
    "StructureCandidate": "_search",
    "StructureSelection": "_search",
    "check_identifiability": "_diagnostics",
    "estimate_frf": "_frf",
    "filter_product": "_svf",
    "fit_armax": "_pem",
    "fit_arx": "_arx",
    "fit_bj": "_pem",
    "fit_frf": "_fit_frf",
    "fit_greybox": "_greybox",
    "fit_iv": "_iv",
    "fit_n4sid": "_subspace",
    "fit_oe": "_pem",
    "fit_pem": "_pem",
    "fit_rls": "_rls",
    "fit_separable": "_separable",
    "fit_tf": "_srivc",
    "fit_tf_greybox": "_tf_greybox",
    "frequency_band": "_band",
    "lstsq": "_ls",
    "modal_parameters": "_modal",
    "select_arx_order": "_order",
    "select_order": "_search",
    "solve_gram": "_ls",
    "state_variable_filter": "_svf",
    "to_polynomial": "_ss_polynomial",
}

__all__ = [
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
    "LeastSquaresResult",
    "ModalParameters",
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
    "fit_frf",
    "fit_greybox",
    "fit_iv",
    "fit_n4sid",
    "fit_oe",
    "fit_pem",
    "fit_rls",
    "fit_separable",
    "fit_tf",
    "fit_tf_greybox",
    "frequency_band",
    "lstsq",
    "modal_parameters",
    "select_arx_order",
    "select_order",
    "solve_gram",
    "state_variable_filter",
    "to_polynomial",
]


#: Building blocks other servoid packages import (through this package, not its modules);
#: not part of the public API (__all__). "module:attribute" where the name differs.
_SHARED = {
    "Covariance": "_covariance",
    "GREYBOX_COVARIANCES": "_covariance",
    "GreyboxCovariance": "_covariance",
    "bootstrap_covariance": "_covariance",
    "filtered_gram": "_covariance",
    "least_squares_covariance": "_covariance",
    "sandwich_covariance": "_covariance",
    "resolve_covariance": "_covariance:resolve",
    "MAX_STARTS": "_diagnostics",
    "draw_starts": "_diagnostics",
    "summarise_starts": "_diagnostics",
    "weakest_parameters": "_diagnostics",
    "lagged_gram": "_gram",
    "piece_transition": "_hybrid",
    "OdeSystem": "_ode",
    "make_system": "_ode",
    "simulation_seconds": "_ode",
    "OdeModel": "_ode_model",
    "fit_ode": "_ode_model",
    "executed_sha256": "_ode_user",
    "load_function": "_ode_user",
    "parse_ref": "_ode_user",
    "Hold": "_svf",
    "check_not_constant": "_channels",
    "frf_channels": "_frf:_io_channels",
    "output_name": "_channels",
}


#: Names that moved into servoid.plants: found there, with a warning, for one release.
_MOVED = {
    "FRICTION_MODELS": "servoid.plants.rigid",
    "InverseDynamicsRegression": "servoid.plants.rigid",
    "fit_closed_loop_oe": "servoid.plants.rigid",
    "fit_inverse_dynamics": "servoid.plants.rigid",
    "inverse_dynamics_regression": "servoid.plants.rigid",
}
_moved = moved_names(__name__, _MOVED)

__getattr__, __dir__ = lazy_exports(__name__, {**_WHERE, **_SHARED}, fallback=_moved)
