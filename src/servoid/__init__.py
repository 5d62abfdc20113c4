"""servoid: identification of servo actuators from test-bench data."""

from ._errors import (
    ChannelError,
    ConvergenceError,
    DataError,
    FileFormatError,
    IdentifiabilityError,
    MissingFileError,
    ModelError,
    OptionError,
    OptionTypeError,
    OutputExistsError,
    ServoidError,
    ServoidWarning,
    SimulationDivergedError,
)
from ._version import __version__

__all__ = [
    "ChannelError",
    "ConvergenceError",
    "DataError",
    "Experiment",
    "ExperimentSet",
    "FileFormatError",
    "IdentifiabilityError",
    "MissingFileError",
    "ModelError",
    "OptionError",
    "OptionTypeError",
    "OutputExistsError",
    "ServoidError",
    "ServoidWarning",
    "SimulationDivergedError",
    "__version__",
    "load_model",
    "load_results",
]


def __getattr__(name: str) -> object:
    """Load :class:`Experiment`, :class:`ExperimentSet`, :func:`load_model` and
    :func:`load_results` on first use (a fast ``--version``)."""
    if name in ("Experiment", "ExperimentSet"):
        from . import data

        return getattr(data, name)
    if name == "load_model":
        from .models import load_model

        return load_model
    if name == "load_results":
        from .workflows import load_results

        return load_results
    raise AttributeError(f"module 'servoid' has no attribute {name!r}")
