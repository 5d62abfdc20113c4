"""Every method ``[identify] method = …`` can name: one line each."""

from __future__ import annotations

from . import _arx, _closedloop, _inverse, _pneumatic
from ._registry import registry

__all__ = ["METHODS"]

METHODS = registry((
    _arx.METHOD,
    _closedloop.METHOD,
    _inverse.METHOD,
    _pneumatic.METHOD,
))
