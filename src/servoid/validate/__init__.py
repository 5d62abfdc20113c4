"""Validation: fit metrics, residual tests, the ValidationReport, and what data cannot fix."""

from ._carry import DataLimit, data_limits
from ._comparison import Comparison, compare
from ._figures import residuals_figure, validation_figure
from ._metrics import fit_percent, nrmse, relative_error, rmse, vaf
from ._nonlinearity import NonlinearityTests, nonlinearity_tests
from ._report import ValidationReport, simulate_from_data, validate
from ._residuals import ResidualAnalysis, residual_analysis
from ._simulate import Replayable, discrete_model, is_replayable, simulate_model

# isort: split
# Building blocks other servoid packages import (through this package, not its modules);
# not part of the public API (__all__).
from ._simulate import INITIALS as INITIALS
from ._simulate import Initial as Initial
from ._simulate import check_signals as check_signals

__all__ = [
    "Comparison",
    "DataLimit",
    "NonlinearityTests",
    "Replayable",
    "ResidualAnalysis",
    "ValidationReport",
    "compare",
    "data_limits",
    "discrete_model",
    "fit_percent",
    "is_replayable",
    "nonlinearity_tests",
    "nrmse",
    "relative_error",
    "residual_analysis",
    "residuals_figure",
    "rmse",
    "simulate_from_data",
    "simulate_model",
    "vaf",
    "validate",
    "validation_figure",
]
