"""Reports: figures, JSON results."""

from ._figures import plot_residuals, plot_validation
from ._json import to_jsonable, write_json

__all__ = ["plot_residuals", "plot_validation", "to_jsonable", "write_json"]
