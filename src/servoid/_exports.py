"""Packages whose names load on first use (PEP 562), so that importing one is cheap.

A package lists each exported name with the private module that defines it; reading the name
imports that module once and keeps the value in the package's namespace.
"""

from __future__ import annotations

import importlib
import sys
from collections.abc import Callable, Mapping
from typing import Any

__all__ = ["lazy_exports"]


def lazy_exports(package: str, where: Mapping[str, str], *,
                 fallback: Callable[[str], Any] | None = None,
                 ) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """Return the ``__getattr__`` and ``__dir__`` of a package that loads its names on first use.

    Parameters
    ----------
    package : str
        The package's ``__name__``.
    where : mapping
        Name → the module of the package that defines it (``"_bench"``), or
        ``"_module:attribute"`` where the name differs from the module's.
    fallback : callable, optional
        ``fallback(name)`` for a name not in ``where`` (a moved name); without it,
        AttributeError.
    """
    def __getattr__(name: str) -> Any:
        home = where.get(name)
        if home is None:
            if fallback is not None:
                return fallback(name)
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        module, _, attribute = home.partition(":")
        value = getattr(importlib.import_module(f"{package}.{module}"), attribute or name)
        setattr(sys.modules[package], name, value)  # later reads skip this hook
        return value

    def __dir__() -> list[str]:
        namespace = sys.modules[package]
        return sorted({*vars(namespace), *getattr(namespace, "__all__", ())})

    return __getattr__, __dir__
