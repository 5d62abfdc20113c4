"""The :class:`Experiment`: sampled signals of one test run with metadata."""

from __future__ import annotations

import math
import mmap
from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import InitVar, dataclass, field, replace
from types import MappingProxyType
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._checks import as_array, as_float, as_int, as_mapping, type_error
from .._errors import ChannelError, DataError, OptionTypeError, check_option

if TYPE_CHECKING:
    from scipy.signal import dlti  # noqa: F401

__all__ = ["DT_RANGE", "ROLES", "Channel", "Experiment", "ExperimentSet", "Role", "check_experiment",
           "timing_problem"]

#: Sample periods servoid computes with [s]: squares and reciprocals (frequencies, variances
#: per second) stay finite in double precision. A dt outside is a damaged or mis-scaled value.
DT_RANGE = (1e-150, 1e150)

Role = Literal["r", "u", "y", "side"]
ROLES: tuple[Role, ...] = ("r", "u", "y", "side")
_ROLE_WORDS = {"r": "reference", "u": "plant input", "y": "output", "side": "side channel"}


@dataclass(frozen=True, eq=False)
class Channel:
    """One sampled signal: name, role, unit and read-only values.

    The values are copied unless they are already immutable (a read-only
    float array whose memory nothing can write, such as a reader's output or
    a read-only memory map) or ``copy=False`` asks to wrap the caller's array
    as a read-only view — then the caller must not change it afterwards.
    """

    name: str
    role: Role
    values: NDArray[np.float64]
    unit: str = ""
    copy: InitVar[bool] = True

    def __post_init__(self, copy: bool) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise DataError(f"channel name must be a non-empty string, got {self.name!r}")
        check_option("channel role", self.role, ROLES)
        if not isinstance(self.unit, str):
            raise type_error(f"unit of channel {self.name!r}", self.unit, "a string")
        values = as_array(f"channel {self.name!r}", self.values, finite=False)
        if values.dtype != np.float64 or (copy and not _immutable(values)):
            values = np.array(values, dtype=np.float64, copy=True)
        elif values.flags.writeable:
            values = values.view()  # the caller's memory, read-only through this view
        if values.ndim != 1:
            raise DataError(
                f"channel {self.name!r} must be 1-D, got an array of shape {values.shape}"
            )
        bad = ~np.isfinite(values)
        if bad.any():
            first = int(np.flatnonzero(bad)[0])
            kind = "NaN" if np.isnan(values[first]) else "inf"
            raise DataError(
                f"channel {self.name!r} has {int(bad.sum())} non-finite value(s), the first "
                f"({kind}) at sample {first}; remove or interpolate them before building an "
                "Experiment"
            )
        values.setflags(write=False)
        object.__setattr__(self, "values", values)

    def with_values(self, values: ArrayLike, unit: str | None = None) -> Channel:
        """Return a copy with new values (and optionally a new unit)."""
        return Channel(self.name, self.role, np.asarray(values), self.unit if unit is None else unit)


def _immutable(values: NDArray[np.float64]) -> bool:
    """True when no one can write the memory behind `values` (a read-only chain of arrays)."""
    base: object = values
    while isinstance(base, np.ndarray):
        if base.flags.writeable:
            return False
        base = base.base
    return base is None or isinstance(base, (bytes, mmap.mmap))


@dataclass(frozen=True, eq=False)
class Experiment:
    """Immutable record of one test run: r, u, y and side channels.

    Build it with :meth:`from_arrays` (or a loader); every operation returns
    a new experiment and leaves this one untouched.

    Parameters
    ----------
    channels : tuple of Channel
        The signals, each with a role ``"r"``, ``"u"``, ``"y"`` or ``"side"``.
    dt : float
        Sample period [s], > 0.
    t0 : float
        Time of the first sample [s].
    name : str
        A label for reports.
    """

    channels: tuple[Channel, ...]
    dt: float
    t0: float = 0.0
    name: str = ""
    notes: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        dt = self.dt
        if isinstance(dt, bool) or not isinstance(dt, (int, float, np.floating, np.integer)):
            raise OptionTypeError(f"dt must be a number of seconds, got {type(dt).__name__}")
        try:
            dt = float(dt)
        except OverflowError:  # an integer past the largest float (10**400)
            raise DataError("dt must be a finite number of seconds > 0, got an integer too "
                            "large for a float") from None
        if not math.isfinite(dt) or dt <= 0:
            raise DataError(f"dt must be > 0 s, got {dt}")
        object.__setattr__(self, "dt", dt)
        object.__setattr__(self, "t0", as_float("t0", self.t0))
        if not isinstance(self.name, str):
            raise type_error("name", self.name, "a string")
        if not isinstance(self.notes, Mapping):
            raise type_error("notes", self.notes, "a mapping")
        if isinstance(self.channels, (str, bytes, Channel)) or not isinstance(
                self.channels, Iterable):
            raise type_error("channels", self.channels, "a sequence of Channel objects")
        channels = tuple(self.channels)
        if not channels:
            raise DataError("an Experiment needs at least one channel")
        for ch in channels:
            if not isinstance(ch, Channel):
                raise OptionTypeError(f"channels must be Channel objects, got {type(ch).__name__}")
        lengths = {ch.name: ch.values.size for ch in channels}
        if len(set(lengths.values())) > 1:
            listed = ", ".join(f"{k}: {v}" for k, v in lengths.items())
            raise DataError(f"channels must have equal lengths, got {listed}")
        names = [ch.name for ch in channels]
        dupes = sorted({n for n in names if names.count(n) > 1})
        if dupes:
            raise DataError(f"channel names must be unique, repeated: {', '.join(dupes)}")
        if channels[0].values.size < 2:
            raise DataError(f"an Experiment needs at least 2 samples, got {channels[0].values.size}")
        problem = timing_problem(self.dt, self.t0, channels[0].values.size)
        if problem:
            raise DataError(f"{problem}; give dt and t0 in seconds")
        object.__setattr__(self, "channels", channels)
        object.__setattr__(self, "notes", MappingProxyType(dict(self.notes)))

    # -- construction -------------------------------------------------------------------------

    @classmethod
    def from_arrays(
        cls,
        dt: float | None = None,
        *,
        r: ArrayLike | None = None,
        u: ArrayLike | None = None,
        y: ArrayLike | None = None,
        side: Mapping[str, ArrayLike] | None = None,
        names: Mapping[str, str | Sequence[str]] | None = None,
        units: Mapping[str, str] | None = None,
        time: ArrayLike | None = None,
        time_tolerance: float = 1e-3,
        t0: float = 0.0,
        name: str = "",
        copy: bool = True,
    ) -> Experiment:
        """Build an experiment from arrays.

        Parameters
        ----------
        dt : float, optional
            Sample period [s]. Required unless ``time`` is given.
        r, u, y : array_like, optional
            Reference, plant input and output, shape ``(N,)`` or ``(N, channels)``.
            Samples run along axis 0; a wider-than-long array is refused, never transposed.
        side : mapping of str to array_like, optional
            Named side channels of shape ``(N,)`` (pressures, temperature, ...).
        names : mapping, optional
            Channel names per role, e.g. ``{"y": "position", "u": ["i1", "i2"]}``.
            Defaults are ``r``, ``u``, ``y`` (``y0``, ``y1``, ... for several channels).
        units : mapping of str to str, optional
            Unit per channel name, e.g. ``{"position": "m"}``.
        time : array_like, optional
            Time stamps [s]; must be uniform within ``time_tolerance`` of ``dt``.
        time_tolerance : float
            Largest accepted deviation of a time step from the mean step, as a fraction of it.
        t0 : float
            Time of the first sample [s] when ``time`` is not given.
        name : str
            A label for reports.
        copy : bool
            Copy the arrays (default). ``False`` wraps float arrays as
            read-only views of the caller's memory (no copy, no extra
            memory for a long record); the caller must then not change
            them. Arrays that are already immutable are never copied.
        """
        names = dict(as_mapping("names", names) if names is not None else {})
        units = dict(as_mapping("units", units) if units is not None else {})
        side = as_mapping("side", side) if side is not None else {}
        time_tolerance = as_float("time_tolerance", time_tolerance, positive=True)
        channels: list[Channel] = []
        for role, data in (("r", r), ("u", u), ("y", y)):
            if data is None:
                continue
            arr = _as_samples(data, role)
            role_names = _role_names(role, arr.shape[1], names.get(role))
            for k, ch_name in enumerate(role_names):
                channels.append(Channel(ch_name, role, arr[:, k], units.get(ch_name, ""),
                                        copy=copy))
        for ch_name, data in side.items():
            arr = as_array(f"side channel {ch_name!r}", data, finite=False)
            if arr.ndim != 1:
                raise DataError(f"side channel {ch_name!r} must be 1-D, got shape {arr.shape}")
            channels.append(Channel(ch_name, "side", arr, units.get(ch_name, ""), copy=copy))
        if time is not None:
            n = channels[0].values.size if channels else 0
            dt_t, t0 = _check_time(as_array("time", time, finite=False), n, time_tolerance)
            if dt is not None and not np.isclose(dt, dt_t, rtol=time_tolerance):
                raise DataError(f"dt = {dt} s disagrees with the time stamps (mean step {dt_t} s)")
            dt = dt_t
        if dt is None:
            raise DataError("give either dt [s] or a time column")
        if not channels:
            raise DataError("an Experiment needs at least one channel: pass r=, u=, y= or side=")
        return cls(tuple(channels), dt, t0=t0, name=name)

    # -- access ---------------------------------------------------------------------------------

    @property
    def n_samples(self) -> int:
        """Number of samples N."""
        return int(self.channels[0].values.size)

    def __len__(self) -> int:
        return self.n_samples

    @property
    def time(self) -> NDArray[np.float64]:
        """Sample times [s]."""
        return self.t0 + self.dt * np.arange(self.n_samples)

    @property
    def duration(self) -> float:
        """Record length N·dt [s]."""
        return self.n_samples * self.dt

    @property
    def names(self) -> tuple[str, ...]:
        """All channel names in order."""
        return tuple(ch.name for ch in self.channels)

    def names_of(self, role: Role) -> tuple[str, ...]:
        """Names of the channels with a given role."""
        check_option("role", role, ROLES)
        return tuple(ch.name for ch in self.channels if ch.role == role)

    def channel(self, name: str) -> Channel:
        """The channel called ``name``.

        Raises :class:`ChannelError` listing the others if it is absent.
        """
        if not isinstance(name, str):
            raise type_error("channel name", name, f"a string, one of: {', '.join(self.names)}")
        for ch in self.channels:
            if ch.name == name:
                return ch
        raise ChannelError(
            f"no channel named {name!r}; this experiment has: {', '.join(self.names)}"
        )

    def __getitem__(self, name: str) -> NDArray[np.float64]:
        if not isinstance(name, str):
            raise OptionTypeError(
                f"index an Experiment by channel name, got {type(name).__name__}; "
                "use exp.slice(start, stop) for a range of samples"
            )
        return self.channel(name).values

    def unit(self, name: str) -> str:
        """Unit of a channel ('' when unknown)."""
        return self.channel(name).unit

    def _stack(self, role: Role) -> NDArray[np.float64] | None:
        cols = [ch.values for ch in self.channels if ch.role == role]
        if not cols:
            return None
        out = np.column_stack(cols)
        out.setflags(write=False)
        return out

    @property
    def r(self) -> NDArray[np.float64] | None:
        """Reference, shape (N, nr), or None."""
        return self._stack("r")

    @property
    def u(self) -> NDArray[np.float64] | None:
        """Plant input, shape (N, nu), or None."""
        return self._stack("u")

    @property
    def y(self) -> NDArray[np.float64] | None:
        """Output, shape (N, ny), or None."""
        return self._stack("y")

    @property
    def side(self) -> dict[str, NDArray[np.float64]]:
        """Side channels by name."""
        return {ch.name: ch.values for ch in self.channels if ch.role == "side"}

    def signal(self, role: Role) -> NDArray[np.float64]:
        """The (N, k) array of the channels with a role.

        Raises :class:`DataError` naming what is missing if there are none.
        """
        arr = self._stack(role)
        if arr is None:
            raise DataError(
                f"this experiment has no {_ROLE_WORDS[role]} ({role!r}) channel; it has: "
                f"{self._describe()}. Map one in the experiment file or pass {role}= to "
                "Experiment.from_arrays"
            )
        return arr

    def require_samples(self, needed: int, purpose: str) -> None:
        """Raise DataError unless there are ``needed`` samples or more."""
        needed = as_int("needed", needed)
        if self.n_samples < needed:
            raise DataError(
                f"{purpose} needs at least {needed} samples, the experiment"
                f"{' ' + repr(self.name) if self.name else ''} has {self.n_samples}"
            )

    def _describe(self) -> str:
        return ", ".join(f"{ch.name} ({ch.role})" for ch in self.channels)

    def __repr__(self) -> str:
        label = f" {self.name!r}" if self.name else ""
        return (
            f"<Experiment{label}: {self.n_samples} samples, dt={self.dt:g} s, "
            f"channels: {self._describe()}>"
        )

    def _repr_html_(self) -> str:
        from .._display import html_block, number

        rows = [(ch.name, _ROLE_WORDS[ch.role], ch.unit, number(float(ch.values.min()), 4),
                 number(float(ch.values.max()), 4), number(float(ch.values.mean()), 4))
                for ch in self.channels]
        return html_block(f"Experiment {self.name}".rstrip(),
                          [("samples", str(self.n_samples)), ("dt", f"{self.dt:g} s"),
                           ("duration", f"{self.n_samples * self.dt:g} s")],
                          ("channel", "role", "unit", "min", "max", "mean"), rows)

    def plot(self) -> Any:
        """Plot every channel against time, one axes per channel.

        Returns
        -------
        matplotlib.figure.Figure
            A figure made by pyplot: Jupyter shows it inline (once, also as a
            cell's value), and in a script ``plt.show()`` or ``plt.savefig()``
            acts on it. Close it with ``plt.close(fig)`` when done.
        """
        from .._pyplot import pyplot_figure

        fig = pyplot_figure((8.0, 1.6 + 1.5 * len(self.channels)))
        axes = fig.subplots(len(self.channels), 1, sharex=True, squeeze=False)[:, 0]
        t = self.t0 + self.dt * np.arange(self.n_samples)
        for ax, ch in zip(axes, self.channels, strict=True):
            ax.plot(t, ch.values, lw=0.8)
            label = ch.name.replace("$", r"\$") + (f" [{ch.unit}]".replace("$", r"\$")
                                                   if ch.unit else "")
            ax.set_ylabel(label)
            ax.grid(alpha=0.3)
        axes[-1].set_xlabel("time [s]")
        fig.tight_layout()
        return fig

    # -- channel operations -------------------------------------------------------------------

    def replace_channels(self, channels: Iterable[Channel], **changes: Any) -> Experiment:
        """A new experiment with other channels (and other fields)."""
        return replace(self, channels=tuple(channels), **changes)

    def select(self, *names: str) -> Experiment:
        """Keep only the named channels, in the order given."""
        if len(names) == 1 and not isinstance(names[0], str):
            if not isinstance(names[0], (list, tuple)):
                raise type_error("names", names[0], "channel names or a list of them")
            names = tuple(names[0])
        return self.replace_channels(self.channel(n) for n in names)

    def drop(self, *names: str) -> Experiment:
        """Remove the named channels."""
        for n in names:
            self.channel(n)
        return self.replace_channels(ch for ch in self.channels if ch.name not in names)

    def rename(self, mapping: Mapping[str, str]) -> Experiment:
        """Rename channels, ``{old: new}``."""
        as_mapping("mapping", mapping)
        for old in mapping:
            self.channel(old)
        return self.replace_channels(
            replace(ch, name=mapping.get(ch.name, ch.name)) for ch in self.channels
        )

    def with_role(self, name: str, role: Role) -> Experiment:
        """Give one channel another role (e.g. side -> plant input)."""
        self.channel(name)
        check_option("role", role, ROLES)
        return self.replace_channels(
            replace(ch, role=role) if ch.name == name else ch for ch in self.channels
        )

    def add_channel(
        self, name: str, values: ArrayLike, role: Role = "side", unit: str = ""
    ) -> Experiment:
        """Append one channel of the same length."""
        return self.replace_channels((*self.channels, Channel(name, role, np.asarray(values), unit)))

    def slice(self, start: int | None = None, stop: int | None = None) -> Experiment:
        """Samples ``start:stop`` as a new experiment; t0 follows."""
        for label, index in (("start", start), ("stop", stop)):
            if index is not None:
                as_int(label, index)
        idx = range(self.n_samples)[slice(start, stop)]
        if len(idx) < 2:
            raise DataError(
                f"slice {start}:{stop} of {self.n_samples} samples leaves {len(idx)}; need >= 2"
            )
        return self.replace_channels(
            (ch.with_values(ch.values[idx.start : idx.stop]) for ch in self.channels),
            t0=self.t0 + idx.start * self.dt,
        )

    # -- preprocessing (implemented in _preprocess) --------------------------------------------

    def calibrate(self, *args: Any, **kwargs: Any) -> Experiment:
        """Apply gain and offset per channel; see :func:`calibrate`."""
        from ._preprocess import calibrate

        return calibrate(self, *args, **kwargs)

    def detrend(self, *args: Any, **kwargs: Any) -> Experiment:
        """Remove mean, trend or operating point; see :func:`detrend`."""
        from ._preprocess import detrend

        return detrend(self, *args, **kwargs)

    def decimate(self, *args: Any, **kwargs: Any) -> Experiment:
        """Anti-aliased decimation; see :func:`servoid.data.decimate`."""
        from ._preprocess import decimate

        return decimate(self, *args, **kwargs)

    def lowpass(self, *args: Any, **kwargs: Any) -> Experiment:
        """Butterworth low-pass filtering; see :func:`lowpass`."""
        from ._preprocess import lowpass

        return lowpass(self, *args, **kwargs)

    def filter(self, *args: Any, **kwargs: Any) -> Experiment:
        """Filter channels with a digital filter; see :func:`filter`."""
        from ._preprocess import filter as _filter

        return _filter(self, *args, **kwargs)

    def split(self, *args: Any, **kwargs: Any) -> tuple[Experiment, Experiment]:
        """Split into estimation and validation parts; see :func:`split`."""
        from ._preprocess import split

        return split(self, *args, **kwargs)


@dataclass(frozen=True, eq=False)
class ExperimentSet:
    """Several experiments fitted together as separate segments.

    Segments are never joined end to end: estimators build their regressors
    within each segment, so no lag reaches across a boundary.
    """

    experiments: tuple[Experiment, ...]

    def __post_init__(self) -> None:
        if isinstance(self.experiments, (str, bytes, Experiment)) or not isinstance(
                self.experiments, Iterable):
            raise type_error("experiments", self.experiments, "a sequence of Experiments")
        exps = tuple(self.experiments)
        if not exps:
            raise DataError("an ExperimentSet needs at least one experiment")
        for e in exps:
            if not isinstance(e, Experiment):
                raise OptionTypeError(f"ExperimentSet holds Experiments, got {type(e).__name__}")
        first = exps[0]
        for k, e in enumerate(exps[1:], start=1):
            if not np.isclose(e.dt, first.dt, rtol=1e-9):
                raise DataError(
                    f"segment {k} has dt = {e.dt} s but segment 0 has {first.dt} s; "
                    "resample to a common rate first"
                )
            sig_a = [(c.name, c.role) for c in first.channels]
            sig_b = [(c.name, c.role) for c in e.channels]
            if sig_a != sig_b:
                raise DataError(
                    f"segment {k} has channels {sig_b}, segment 0 has {sig_a}; "
                    "select and rename to the same channels first"
                )
        object.__setattr__(self, "experiments", exps)

    @property
    def dt(self) -> float:
        """Common sample period [s]."""
        return self.experiments[0].dt

    @property
    def n_samples(self) -> int:
        """Samples over all segments."""
        return sum(e.n_samples for e in self.experiments)

    def __iter__(self) -> Iterator[Experiment]:
        return iter(self.experiments)

    def __len__(self) -> int:
        return len(self.experiments)

    def __getitem__(self, k: int) -> Experiment:
        return self.experiments[k]


def as_segments(data: Experiment | ExperimentSet) -> tuple[Experiment, ...]:
    """The experiments of ``data`` as a tuple of segments."""
    if isinstance(data, Experiment):
        return (data,)
    if isinstance(data, ExperimentSet):
        return data.experiments
    raise OptionTypeError(
        f"data must be an Experiment or ExperimentSet (build one with Experiment.from_arrays "
        f"or read_experiment), got {type(data).__name__}"
    )


def check_experiment(value: object, name: str = "data") -> Experiment:
    """Return ``value`` if it is an Experiment, else an OptionTypeError naming ``name``."""
    if not isinstance(value, Experiment):
        raise OptionTypeError(
            f"{name} must be an Experiment (build one with Experiment.from_arrays or "
            f"read_experiment), got {type(value).__name__}"
        )
    return value


def _as_samples(data: ArrayLike, role: str) -> NDArray[np.float64]:
    arr = as_array(role, data, finite=False)
    if arr.ndim == 1:
        return arr[:, None]
    if arr.ndim != 2:
        raise DataError(f"{role} must be 1-D or 2-D (samples, channels), got shape {arr.shape}")
    if arr.shape[1] > arr.shape[0]:
        raise DataError(
            f"{role} has shape {arr.shape}: more channels than samples. Samples run along "
            f"axis 0; if the array is (channels, samples), pass {role}.T"
        )
    return arr


def _role_names(role: str, k: int, given: str | Sequence[str] | None) -> list[str]:
    if given is None:
        return [role] if k == 1 else [f"{role}{i}" for i in range(k)]
    listed = [given] if isinstance(given, str) else list(given)
    if len(listed) != k:
        raise DataError(f"{len(listed)} name(s) given for {k} {role} channel(s): {listed}")
    return listed


#: Time stamps checked at a time (:func:`_check_time`).
_CHUNK = 1 << 16


def timing_problem(dt: float, t0: float, n: int) -> str | None:
    """What makes ``dt``, ``t0`` and ``n`` samples unusable as a time base, or None.

    Parameters
    ----------
    dt : float
        Sample period [s], finite and > 0.
    t0 : float
        Time of the first sample [s], finite.
    n : int
        Number of samples.

    Returns
    -------
    str or None
        The problem in words (``"dt = 5e-324 s is outside ..."``), or None.
    """
    low, high = DT_RANGE
    if not low <= dt <= high:
        return (f"dt = {dt:g} s is outside the sample periods servoid computes with ({low:g} … "
                f"{high:g} s: beyond them frequencies or variances overflow)")
    last = abs(t0) + dt * n
    if not np.isfinite(last):
        return f"dt = {dt:g} s and t0 = {t0:g} s: the record's time stamps overflow double precision"
    if float(np.spacing(last)) > dt:
        return (f"t0 = {t0:g} s is too large for dt = {dt:g} s: near {last:.3g} s a double "
                f"resolves only {float(np.spacing(last)):.3g} s, more than a sample period, so "
                "the sample times cannot be told apart")
    return None


def _check_time(time: NDArray[np.float64], n: int, tol: float) -> tuple[float, float]:
    if time.ndim != 1 or time.size != n:
        raise DataError(f"time has shape {time.shape}, expected ({n},) to match the channels")
    if n < 2:
        raise DataError(f"time stamps give no sample period: {n} sample(s), need >= 2")
    # a chunk of steps at a time: at 1e7 stamps the whole-record temporaries were 240 MB
    if not all(np.all(np.isfinite(time[lo : lo + _CHUNK])) for lo in range(0, n, _CHUNK)):
        raise DataError("time column has non-finite values")
    dt = float((time[-1] - time[0]) / (n - 1))
    if dt <= 0:
        raise DataError(f"time stamps must increase; mean step is {dt} s")
    worst, worst_dev = 0, -1.0
    for lo in range(0, n - 1, _CHUNK):
        dev = np.abs(np.diff(time[lo : min(lo + _CHUNK, n - 1) + 1]) - dt)
        k = int(np.argmax(dev))
        if dev[k] > worst_dev:  # the first largest step, as one argmax over all would find
            worst, worst_dev = lo + k, float(dev[k])
    if worst_dev > tol * dt:
        step = float(time[worst + 1] - time[worst])
        raise DataError(
            f"time stamps are not uniform: step {worst} ({time[worst]:.6g} s -> "
            f"{time[worst + 1]:.6g} s) is {step:.6g} s against a mean of {dt:.6g} s "
            f"(tolerance {tol:.0e} relative). Resample to a uniform grid or split the record "
            "at the gap; for a logger's time-stamp jitter raise the tolerance (pass jitter=)"
        )
    return dt, float(time[0])
