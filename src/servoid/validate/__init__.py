"""Validation: fit metrics, residual tests and the ValidationReport."""

from ._metrics import fit_percent, nrmse, relative_error, rmse, vaf
from ._report import ValidationReport, compare, simulate_from_data, validate
from ._residuals import ResidualAnalysis, residual_analysis
from ._simulate import Replayable, discrete_model, is_replayable, simulate_model

__all__ = [
    "Replayable",
    "ResidualAnalysis",
    "ValidationReport",
    "compare",
    "discrete_model",
    "fit_percent",
    "is_replayable",
    "nrmse",
    "relative_error",
    "residual_analysis",
    "rmse",
    "simulate_from_data",
    "simulate_model",
    "vaf",
    "validate",
]
