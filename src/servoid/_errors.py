"""Exceptions and warnings raised by servoid.

Every error servoid raises on purpose derives from :class:`ServoidError`
and from the built-in exception a Python user would expect, so both
``except ServoidError`` and ``except ValueError`` work::

    ServoidError
    ├── DataError(ValueError)          bad signal values, shapes, sampling
    │   └── FileFormatError            malformed, truncated or unreadable file
    ├── MissingFileError(FileNotFoundError)  an input file does not exist
    ├── ChannelError(KeyError)         a named channel (or parameter) is missing
    ├── OptionError(ValueError)        an option outside its set of values
    ├── OptionTypeError(TypeError)     an option or argument of the wrong type
    ├── IdentifiabilityError(ValueError)  data cannot determine the parameters
    ├── ModelError(ValueError)         a model that cannot do what is asked
    ├── ConvergenceError(RuntimeError) an iterative solver failed
    └── OutputExistsError(FileExistsError)  refusing to overwrite a file

    ServoidWarning(UserWarning)        suspicious but valid results
"""

from __future__ import annotations

from collections.abc import Iterable

__all__ = [
    "ChannelError",
    "ConvergenceError",
    "DataError",
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
    "check_option",
]


class ServoidError(Exception):
    """Root of every error servoid raises on purpose."""


class DataError(ServoidError, ValueError):
    """Signal values, shapes or sampling are not usable."""


class FileFormatError(DataError):
    """A file is malformed, truncated or not of the expected format."""


class MissingFileError(ServoidError, FileNotFoundError):
    """An input file (or folder) named by the user does not exist."""


class ChannelError(ServoidError, KeyError):
    """A channel (or a parameter) named by the user does not exist."""

    def __str__(self) -> str:  # KeyError quotes its message; keep it readable
        return str(self.args[0]) if self.args else ""


class OptionError(ServoidError, ValueError):
    """An option value outside its set of valid values."""


class OptionTypeError(ServoidError, TypeError):
    """An option of the wrong type (text where a number belongs)."""


class IdentifiabilityError(ServoidError, ValueError):
    """The data cannot determine the parameters asked for."""


class ModelError(ServoidError, ValueError):
    """A model cannot perform the operation asked of it."""


class SimulationDivergedError(ModelError):
    """A model's free run left every finite number on a record.

    ``sample`` is the first sample whose simulated value is not finite.
    """

    def __init__(self, message: str, sample: int) -> None:
        super().__init__(message)
        self.sample = int(sample)

    def __reduce__(self) -> tuple[object, ...]:  # picklable (Dask ships errors between processes)
        return (type(self), (str(self), self.sample))


class ConvergenceError(ServoidError, RuntimeError):
    """An iterative solver did not converge."""


class OutputExistsError(ServoidError, FileExistsError):
    """An output file exists and overwriting was not allowed."""


class ServoidWarning(UserWarning):
    """A valid but suspicious result (unstable, poorly excited)."""


def check_option(name: str, value: object, valid: Iterable[object]) -> None:
    """Raise :class:`OptionError` unless ``value`` is one of ``valid``."""
    choices = tuple(valid)
    try:
        found = value in choices
    except (TypeError, ValueError):  # an array compares element-wise: never an option
        found = False
    if found is not True:
        listed = ", ".join(repr(c) for c in choices)
        raise OptionError(f"{name} must be one of {listed}; got {value!r}")
