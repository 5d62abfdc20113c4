"""Warnings that point at the caller's line, not at servoid's source.

Every warning servoid gives goes through :func:`warn`.  Python attributes a
warning to the frame ``stacklevel`` steps up; a fixed number is wrong as
soon as a function is reached by another path (a workflow calling an
estimator, scipy's solver calling a residual function).  :func:`warn`
counts instead: the warning is attributed to the line that called into
servoid — the caller of the outermost servoid frame on the stack — so
``warnings.catch_warnings(record=True)`` and Python's own display name the
user's script and line, and a filter on the user's module applies.
"""

from __future__ import annotations

import sys
import warnings

from ._errors import ServoidWarning

__all__ = ["warn"]


def warn(message: str | Warning, category: type[Warning] = ServoidWarning) -> None:
    """Warn, attributed to the line outside servoid that led here.

    Parameters
    ----------
    message : str or Warning
        The text (a Warning instance keeps its own category).
    category : type
        Default :class:`~servoid.ServoidWarning`.
    """
    frame = sys._getframe(1)  # the call site; stacklevel 2 names it
    level, outermost = 2, 2
    while frame is not None:
        if _in_servoid(frame.f_globals.get("__name__", "")):
            outermost = level
        frame = frame.f_back  # type: ignore[assignment]
        level += 1
    warnings.warn(message, category, stacklevel=outermost + 1)


def _in_servoid(module: object) -> bool:
    return isinstance(module, str) and (module == "servoid" or module.startswith("servoid."))
