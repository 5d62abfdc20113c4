"""Validation: fit metrics, residual tests and the ValidationReport."""

from ._metrics import fit_percent, nrmse, relative_error, rmse, vaf
from ._report import ValidationReport, simulate_from_data, validate
from ._residuals import ResidualAnalysis, residual_analysis

__all__ = [
    "ResidualAnalysis",
    "ValidationReport",
    "fit_percent",
    "nrmse",
    "relative_error",
    "residual_analysis",
    "rmse",
    "simulate_from_data",
    "vaf",
    "validate",
]
