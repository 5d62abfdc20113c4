"""Data that cannot carry a model's parameters: a step, one sine, drift, a clipped signal.

A parameter interval is only as good as the information the record holds
about it.  Some records hold far less than their length suggests, and the
estimator cannot tell: its covariance is computed from the model's own
structure, so it prints narrow intervals for numbers the data never fixed.
:func:`data_limits` looks at the signals before any model is trusted and
names what each kind of record cannot fix:

``step``
    The excitation changes level once or twice and otherwise stands still.
    A step fixes the static gain and the slowest time constant; what is
    faster than the step's edge, and a model of higher order, rests on
    the noise.
``one sine``
    Nearly all the excitation's power sits in one spectral line.  One
    frequency fixes two numbers — the gain and the phase there — and
    nothing about the rest of the frequency response.
``drift``
    A straight line explains most of the output's variance while the
    excitation swings about zero with no trend of its own.  A drift that no
    input explains biases the low-frequency part of the model: the static
    gain and the slow poles.  An excitation with a mean ramps the output of
    an integrating plant just as well, so drift is not judged then.
``clipped``
    A signal sits on its largest or smallest value for runs of samples,
    far more often than on any other value: a saturated actuator or a
    clipped sensor.  While clipped, the signal is not the one a linear
    model sees.

The thresholds are conservative (each is stated with its check) so that a
PRBS, a multisine, a chirp or a noisy record does not trip them; a check
that fires is a verdict in words, not an error.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._checks import type_error
from ..data import Experiment, ExperimentSet, as_segments

__all__ = ["DataLimit", "data_limits"]

#: Share of the excitation's (detrended, windowed) power within ±3 lines of its peak: one sine.
_SINE_SHARE = 0.95
#: Share of the output's variance a straight line explains, with none in the excitation: drift.
_DRIFT_SHARE = 0.5
_DRIFT_INPUT = 0.05
#: An excitation whose mean is within this share of its range swings about zero.
_CENTRED = 0.1
#: A jump larger than this share of the range is an edge; a step has at most two.
_EDGE = 0.25
#: Largest spread (std) between the edges of a step, as a share of its range.
_LEVEL = 0.1
#: Share of samples on one extreme value, and its multiple of the median value count: clipped.
_CLIP_SHARE = 0.02
_CLIP_RATIO = 10.0
#: Distinct values a signal needs before clipping is judged (a binary PRBS sits on its extremes).
_CLIP_LEVELS = 20


@dataclass(frozen=True)
class DataLimit:
    """One thing a record cannot fix.

    Attributes
    ----------
    name : str
        ``"step"``, ``"one sine"``, ``"drift"`` or ``"clipped"``.
    channel : str
        The channel it was found on.
    value : str
        The evidence, e.g. ``"2 edges"`` or ``"99 % of the power at 1.5 Hz"``.
    meaning : str
        What the data cannot fix, and what to do about it.
    """

    name: str
    channel: str
    value: str
    meaning: str

    def text(self) -> str:
        """One sentence: channel, evidence, meaning."""
        return f"{self.channel!r}: {self.name} ({self.value}): {self.meaning}"

    def to_dict(self) -> dict[str, str]:
        """Plain data."""
        return {"name": self.name, "channel": self.channel, "value": self.value,
                "meaning": self.meaning}


def data_limits(
    data: Experiment | ExperimentSet,
    *,
    excitation: str | None = None,
    outputs: tuple[str, ...] | list[str] | None = None,
    inputs: tuple[str, ...] | list[str] | None = None,
) -> tuple[DataLimit, ...]:
    """What a record cannot fix: a step, one sine, drift, clipping.

    Parameters
    ----------
    data : Experiment or ExperimentSet
        The record(s) the model is fitted to.
    excitation : str, optional
        The channel that excites the system (the input in open loop, the
        reference in closed loop); default: the only ``r`` channel, else
        the only ``u`` channel.
    outputs : sequence of str, optional
        Output channels checked for drift and clipping; default: every
        ``y`` channel.
    inputs : sequence of str, optional
        Input channels checked for clipping; default: every ``u`` channel.

    Returns
    -------
    tuple of DataLimit
        Empty when nothing was found.

    Examples
    --------
    >>> t = np.arange(2000) * 0.01
    >>> exp = Experiment.from_arrays(0.01, u=np.where(t > 5, 1.0, 0.0), y=np.tanh(t))
    >>> [d.name for d in data_limits(exp)]
    ['step']
    """
    segments = as_segments(data)
    first = segments[0]
    if excitation is None:
        for role in ("r", "u"):
            names = first.names_of(role)  # type: ignore[arg-type]
            if len(names) == 1:
                excitation = names[0]
                break
    elif not isinstance(excitation, str):
        raise type_error("excitation", excitation, "a channel name")
    outputs = list(first.names_of("y")) if outputs is None else list(outputs)
    inputs = list(first.names_of("u")) if inputs is None else list(inputs)
    found: list[DataLimit] = []
    dt = first.dt
    if excitation is not None:
        x = [_values(seg[excitation]) for seg in segments]
        step = _step(x)
        if step is not None:
            found.append(DataLimit("step", excitation, step, (
                "a step fixes the static gain and the slowest time constant, not the faster "
                "dynamics nor a higher order: their intervals rest on the noise. Excite a band "
                "(a PRBS or a multisine: servoid excite)")))
        else:
            sine = _sine(x, dt)
            if sine is not None:
                found.append(DataLimit("one sine", excitation, sine, (
                    "one frequency fixes two numbers, the gain and the phase there; a model "
                    "with more parameters is not determined by this record. Excite a band (a "
                    "PRBS or a multisine: servoid excite)")))
    for name in outputs:
        y = [_values(seg[name]) for seg in segments]
        share = _trend_share(y)
        # an input with a mean (or a trend) ramps an integrating plant's output: that is
        # dynamics, not drift, and the data alone cannot tell the two apart
        x = [] if excitation is None else [_values(seg[excitation]) for seg in segments]
        quiet = excitation is not None and _trend_share(x) < _DRIFT_INPUT and _centred(x)
        if share > _DRIFT_SHARE and quiet:
            found.append(DataLimit("drift", name, f"a straight line explains "
                                   f"{100 * share:.0f} % of its variance", (
                "a drift that no input explains biases the static gain and the slow poles "
                "(unless the plant integrates). Remove it ([preprocess] detrend) or record "
                "after the bench has settled")))
    for name in [*inputs, *outputs]:
        clipped = _clipped([_values(seg[name]) for seg in segments])
        if clipped is not None:
            found.append(DataLimit("clipped", name, clipped, (
                "while it sits on its limit the signal is not the one a linear model sees (a "
                "saturated actuator or a clipped sensor), which biases every parameter. Lower "
                "the amplitude, or cut the clipped stretches out of the record")))
    return tuple(found)


def _values(x: ArrayLike) -> NDArray[np.float64]:
    v = np.asarray(x, dtype=float)
    return v[np.isfinite(v)]


def _range(pieces: list[NDArray[np.float64]]) -> float:
    allx = np.concatenate(pieces)
    if allx.size == 0:
        return 0.0
    return float(np.max(allx) - np.min(allx))


def _step(pieces: list[NDArray[np.float64]]) -> str | None:
    """'n edges' when the signal changes level at most twice and is level between."""
    span = _range(pieces)
    if span <= 0:
        return None
    edges = 0
    rough = 0.0
    for p in pieces:
        at = np.flatnonzero(np.abs(np.diff(p)) > _EDGE * span) + 1
        edges += at.size
        for part in np.split(p, at):
            if part.size > 1:
                rough = max(rough, float(np.std(part)))
    if 1 <= edges <= 2 and rough <= _LEVEL * span:
        return f"{edges} edge{'s' if edges > 1 else ''}, level between"
    return None


def _sine(pieces: list[NDArray[np.float64]], dt: float) -> str | None:
    """'N % of the power at f Hz' when one line holds nearly all of it."""
    x = max(pieces, key=lambda p: p.size)
    if x.size < 64:
        return None
    t = np.arange(x.size)
    x = x - np.polyval(np.polyfit(t, x, 1), t)
    spectrum = np.abs(np.fft.rfft(x * np.hanning(x.size))) ** 2
    spectrum[0] = 0.0
    total = float(spectrum.sum())
    if total <= 0:
        return None
    k = int(np.argmax(spectrum))
    share = float(spectrum[max(k - 3, 0): k + 4].sum()) / total
    if share < _SINE_SHARE:
        return None
    return f"{100 * share:.0f} % of the power at {k / (x.size * dt):.3g} Hz"


def _trend_share(pieces: list[NDArray[np.float64]]) -> float:
    """Share of the variance a straight line (per segment) explains."""
    explained = total = 0.0
    for p in pieces:
        if p.size < 3:
            continue
        t = np.arange(p.size, dtype=float)
        centred = p - p.mean()
        tc = t - t.mean()
        slope = float(tc @ centred) / float(tc @ tc)
        explained += slope**2 * float(tc @ tc)
        total += float(centred @ centred)
    return explained / total if total > 0 else 0.0


def _centred(pieces: list[NDArray[np.float64]]) -> bool:
    """The signal swings about zero: its mean is within 10 % of its range."""
    allx = np.concatenate(pieces)
    span = float(np.max(allx) - np.min(allx)) if allx.size else 0.0
    return span > 0 and abs(float(np.mean(allx))) <= _CENTRED * span


def _clipped(pieces: list[NDArray[np.float64]]) -> str | None:
    """'N % of samples at V' when one extreme value holds runs and far more than its share."""
    allx = np.concatenate(pieces)
    if allx.size < 100:
        return None
    values, counts = np.unique(allx, return_counts=True)
    if values.size < _CLIP_LEVELS:
        return None
    typical = float(np.median(counts))
    for value, count in ((values[-1], counts[-1]), (values[0], counts[0])):
        share = count / allx.size
        if share < _CLIP_SHARE or count < _CLIP_RATIO * typical:
            continue
        runs = max(_longest_run(p == value) for p in pieces)
        if runs >= 3:
            return f"{100 * share:.1f} % of the samples at {value:.6g}, in runs of up to {runs}"
    return None


def _longest_run(mask: NDArray[np.bool_]) -> int:
    if not np.any(mask):
        return 0
    padded = np.concatenate([[0], mask.astype(np.int8), [0]])
    edges = np.flatnonzero(np.diff(padded))
    return int(np.max(edges[1::2] - edges[::2]))
