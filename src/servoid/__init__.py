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
)
from .data import Experiment, ExperimentSet

__version__ = "0.1.0"

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
    "__version__",
]
