"""Old import paths of names that moved, kept for one release with a warning.

Each actuator's code moved into its own subpackage of :mod:`servoid.plants`
(``servoid.actuators``, ``servoid.multistep`` and the actuator-specific
names of ``servoid.closedloop``, ``servoid.bench``, ``servoid.estimate`` and
``servoid.workflows``).  The old packages answer for those names through
:func:`moved_names`: the object comes from its new home, with a
:class:`DeprecationWarning` that names the new path at the caller's line.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping
from typing import Any

from ._warn import warn

__all__ = ["moved_names"]


def moved_names(old: str, table: Mapping[str, str]) -> Callable[[str], Any]:
    """Return a module ``__getattr__`` that finds ``table``'s names in their new package.

    Parameters
    ----------
    old : str
        The package the names were in (``"servoid.actuators"``).
    table : mapping
        Name → the package it moved to (``"servoid.plants.ehsa"``).
    """
    def __getattr__(name: str) -> Any:
        new = table.get(name)
        if new is None:
            raise AttributeError(f"module {old!r} has no attribute {name!r}")
        warn(f"{old}.{name} moved to {new}.{name}; import it from there ({old}.{name} goes in "
             "the next release)", DeprecationWarning)
        return getattr(importlib.import_module(new), name)

    return __getattr__
