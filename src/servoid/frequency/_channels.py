"""Channel look-up shared by the estimators of this package."""

from __future__ import annotations

import numpy as np

from .._errors import ChannelError, DataError, OptionTypeError
from ..data import ROLES, Channel, Experiment

__all__ = ["channel", "check_varies"]


def channel(exp: Experiment, key: object, what: str, param: str) -> Channel:
    """The channel a name or a role (naming exactly one channel) points to."""
    if not isinstance(key, str):
        raise OptionTypeError(f"{param} must be a channel name or role, got {key!r}")
    if key in exp.names:
        return exp.channel(key)
    if key in ROLES:
        names = exp.names_of(key)  # type: ignore[arg-type]
        if len(names) == 1:
            return exp.channel(names[0])
        if len(names) > 1:
            raise DataError(f"several {what} channels of role {key!r} ({', '.join(names)}): "
                            f"pass {param}=<channel name>")
    raise ChannelError(f"no channel or role {key!r} for the {what}; this experiment has: "
                       f"{', '.join(f'{c.name} ({c.role})' for c in exp.channels)}")


def check_varies(ch: Channel, what: str) -> None:
    """Refuse a constant channel: it excites nothing."""
    x = ch.values
    hi, lo = float(np.max(x)), float(np.min(x))
    if hi - lo <= 1e-13 * max(abs(hi), abs(lo), np.finfo(float).tiny):
        raise DataError(
            f"the {what} channel {ch.name!r} is constant ({x[0]:g} throughout): a frequency "
            "response needs an input that excites the system; check the channel mapping or "
            "the record"
        )
