"""Every method ``[identify] method = …`` can name: one line each; a plant's come with it."""

from __future__ import annotations

from ..plants import PLANTS
from . import _arx, _closedloop, _closedloop_any, _frf, _inverse, _n4sid, _pem, _pneumatic, _tf
from ._blocks import HAMMERSTEIN, HAMMERSTEIN_WIENER, WIENER
from ._greybox import GREYBOX
from ._narx import METHOD as NARX
from ._registry import registry

__all__ = ["METHODS"]

METHODS = registry((
    _arx.METHOD,
    _pem.OE,
    _pem.ARMAX,
    _pem.BJ,
    _tf.TF,
    _n4sid.N4SID,
    _frf.FRF,
    _closedloop_any.TWO_STAGE,
    _closedloop_any.CLIV,
    _closedloop_any.INDIRECT,
    _closedloop.METHOD,
    _inverse.METHOD,
    _pneumatic.METHOD,
    HAMMERSTEIN,
    WIENER,
    HAMMERSTEIN_WIENER,
    NARX,
    GREYBOX,
    *(method for plant in PLANTS.values() for method in plant.load("methods")),
))
