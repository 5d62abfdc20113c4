"""User text in figures: channel names, units and labels shown as typed (see servoid._drawing)."""

from __future__ import annotations

from .._drawing import plain

__all__ = ["plain"]
