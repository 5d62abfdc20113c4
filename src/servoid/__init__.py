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


def __getattr__(name: str) -> object:
    """Load :class:`Experiment` and :class:`ExperimentSet` on first use (a fast ``--version``)."""
    if name in ("Experiment", "ExperimentSet"):
        from . import data

        return getattr(data, name)
    raise AttributeError(f"module 'servoid' has no attribute {name!r}")
