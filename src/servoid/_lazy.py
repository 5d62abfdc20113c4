"""Modules loaded on first use, so that ``import servoid…`` and ``servoid --help`` start fast.

``scipy.signal``, ``scipy.stats``, ``scipy.optimize`` and ``scipy.linalg``
take most of a second to import and are needed only inside functions: modules bind them here by name and the real
import happens at the first attribute access::

    from .._lazy import signal as sps   # then sps.lfilter(...) as before
"""

from __future__ import annotations

import importlib
from types import ModuleType
from typing import Any

__all__ = ["fft", "integrate", "interpolate", "linalg", "optimize", "signal", "stats"]


class _LazyModule(ModuleType):
    """A stand-in that imports the named module when an attribute is first read."""

    def __init__(self, name: str) -> None:
        super().__init__(name)
        self._target: ModuleType | None = None

    def __getattr__(self, attr: str) -> Any:
        if attr.startswith("__") and attr.endswith("__"):
            raise AttributeError(attr)
        if self._target is None:
            self._target = importlib.import_module(self.__name__)
        return getattr(self._target, attr)

    def __dir__(self) -> list[str]:
        if self._target is None:
            self._target = importlib.import_module(self.__name__)
        return dir(self._target)


fft: Any = _LazyModule("scipy.fft")
integrate: Any = _LazyModule("scipy.integrate")
interpolate: Any = _LazyModule("scipy.interpolate")
linalg: Any = _LazyModule("scipy.linalg")
optimize: Any = _LazyModule("scipy.optimize")
signal: Any = _LazyModule("scipy.signal")
stats: Any = _LazyModule("scipy.stats")
