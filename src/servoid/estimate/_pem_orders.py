"""Orders, parameter layout and data preparation of the polynomial estimators.

The general structure is ``A(q) y(t) = Σ_i B_i(q)/F_i(q) u_i(t − nk_i) +
C(q)/D(q) e(t)`` (Ljung, *System Identification*, 2nd ed., §4.2).  The
parameter vector θ is laid out as ``a1…a_na``, then per input ``b0…``,
``f1…``, then ``c1…``, ``d1…``; :class:`PemOrders` validates the orders and
maps θ to the polynomials and back.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from .._checks import as_int
from .._errors import DataError, check_option
from ..data import Experiment, ExperimentSet, as_segments
from ..models import PolynomialModel
from ._arx import _per_input
from ._channels import LARGEST_VALUE, check_magnitude, check_not_constant, output_name
from ._pem_kernels import sum_squares

__all__ = ["LARGEST_VALUE", "PemOrders", "Polys", "SignalData", "check_record", "prepare"]


@dataclass(frozen=True, slots=True)
class Polys:
    """The polynomials of one parameter vector (monic A, F_i, C, D)."""

    a: NDArray[np.float64]
    b: tuple[NDArray[np.float64], ...]
    f: tuple[NDArray[np.float64], ...]
    c: NDArray[np.float64]
    d: NDArray[np.float64]


class PemOrders:
    """Validated orders of the general polynomial structure."""

    __slots__ = ("na", "nb", "nc", "nd", "nf", "nk")

    def __init__(
        self,
        na: int,
        nb: int | Sequence[int],
        nc: int,
        nd: int,
        nf: int | Sequence[int],
        nk: int | Sequence[int],
        n_inputs: int,
    ) -> None:
        self.na = as_int("na", na, minimum=0)
        self.nb = _per_input("nb", nb, n_inputs, minimum=1)
        self.nc = as_int("nc", nc, minimum=0)
        self.nd = as_int("nd", nd, minimum=0)
        self.nf = _per_input("nf", nf, n_inputs, minimum=0)
        self.nk = _per_input("nk", nk, n_inputs, minimum=0)

    @property
    def n_inputs(self) -> int:
        """Number of inputs."""
        return len(self.nb)

    @property
    def n_parameters(self) -> int:
        """Number of coefficients in θ."""
        return self.na + sum(self.nb) + sum(self.nf) + self.nc + self.nd

    @property
    def max_lag(self) -> int:
        """Longest delay of any polynomial [samples]."""
        lags = [self.na, self.nc, self.nd, *self.nf]
        lags += [k + b - 1 for k, b in zip(self.nk, self.nb, strict=True)]
        return max(lags)

    @property
    def noise_free(self) -> bool:
        """Whether C = D = 1 (no noise model to filter with)."""
        return self.nc == 0 and self.nd == 0

    def blocks(self) -> tuple[slice, tuple[slice, ...], tuple[slice, ...], slice, slice]:
        """Slices of θ holding a, each b_i, each f_i, c and d."""
        o = self.na
        a = slice(0, o)
        bs, fs = [], []
        for nb, nf in zip(self.nb, self.nf, strict=True):
            bs.append(slice(o, o + nb))
            fs.append(slice(o + nb, o + nb + nf))
            o += nb + nf
        c = slice(o, o + self.nc)
        d = slice(o + self.nc, o + self.nc + self.nd)
        return a, tuple(bs), tuple(fs), c, d

    def split(self, theta: NDArray[np.float64]) -> Polys:
        """The polynomials of θ (monic ones with their leading 1)."""
        a, bs, fs, c, d = self.blocks()
        one = np.ones(1)
        return Polys(
            np.concatenate([one, theta[a]]),
            tuple(np.array(theta[s]) for s in bs),
            tuple(np.concatenate([one, theta[s]]) for s in fs),
            np.concatenate([one, theta[c]]),
            np.concatenate([one, theta[d]]),
        )

    def join(self, polys: Polys) -> NDArray[np.float64]:
        """θ from the polynomials (inverse of :meth:`split`)."""
        parts = [polys.a[1:]]
        for b, f in zip(polys.b, polys.f, strict=True):
            parts += [b, f[1:]]
        parts += [polys.c[1:], polys.d[1:]]
        return np.concatenate(parts).astype(float)

    def names(self, inputs: Sequence[str]) -> tuple[str, ...]:
        """Parameter names in θ order (``<input>:`` prefix when several inputs)."""
        out = [f"a{k}" for k in range(1, self.na + 1)]
        for name, nb, nf in zip(inputs, self.nb, self.nf, strict=True):
            prefix = "" if len(inputs) == 1 else f"{name}:"
            out += [f"{prefix}b{j}" for j in range(nb)]
            out += [f"{prefix}f{j}" for j in range(1, nf + 1)]
        out += [f"c{k}" for k in range(1, self.nc + 1)]
        out += [f"d{k}" for k in range(1, self.nd + 1)]
        return tuple(out)

    def model(
        self,
        theta: NDArray[np.float64],
        dt: float,
        noise_variance: float,
        inputs: Sequence[str],
        output: str,
    ) -> PolynomialModel:
        """The :class:`PolynomialModel` of θ."""
        p = self.split(np.asarray(theta, dtype=float))
        return PolynomialModel(
            p.a, p.b, self.nk, dt, c=p.c, d=p.d, f=p.f,
            noise_variance=float(noise_variance), input_names=tuple(inputs), output_name=output,
        )

    def as_options(self) -> dict[str, object]:
        """The orders as JSON-friendly options (lists per input)."""
        return {"na": self.na, "nb": list(self.nb), "nc": self.nc, "nd": self.nd,
                "nf": list(self.nf), "nk": list(self.nk)}

    def __repr__(self) -> str:
        def one(v: tuple[int, ...]) -> object:
            return v[0] if len(v) == 1 else list(v)
        return (f"PEM(na={self.na}, nb={one(self.nb)}, nc={self.nc}, nd={self.nd}, "
                f"nf={one(self.nf)}, nk={one(self.nk)})")


@dataclass(frozen=True, eq=False)
class SignalData:
    """The channels an estimator reads, per segment (read-only views)."""

    y: tuple[NDArray[np.float64], ...]
    u: tuple[tuple[NDArray[np.float64], ...], ...]
    r: tuple[tuple[NDArray[np.float64], ...], ...]
    inputs: tuple[str, ...]
    output: str
    references: tuple[str, ...]
    dt: float

    @property
    def lengths(self) -> tuple[int, ...]:
        """Samples per segment."""
        return tuple(y.size for y in self.y)

    def rows(self, start: int) -> int:
        """Number of equations t >= start over all segments."""
        return sum(max(n - start, 0) for n in self.lengths)

    @property
    def y_rms(self) -> float:
        """Root mean square of the output over all segments."""
        total = sum(float(sum_squares(y, 0)) for y in self.y)
        return float(np.sqrt(total / sum(self.lengths)))


def prepare(
    data: Experiment | ExperimentSet,
    input: str,
    output: str | None,
    *,
    with_reference: bool = False,
) -> SignalData:
    """Read and check the channels: names, magnitude and excitation.

    Raises
    ------
    DataError
        A missing channel, or values so large that their squares overflow.
    IdentifiabilityError
        A constant input.
    """
    check_option("input", input, ("u", "r"))
    segments = as_segments(data)
    first = segments[0]
    inputs = first.names_of(input)  # type: ignore[arg-type]
    if not inputs:
        first.signal(input)  # type: ignore[arg-type]  # raises a DataError naming what exists
    out_name = output_name(first, output)
    refs: tuple[str, ...] = ()
    if with_reference:
        refs = first.names_of("r")
        if not refs:
            raise DataError(
                f"instrument='r' needs a reference channel (role 'r'); this experiment has "
                f"{', '.join(first.names)}. Record the reference or use instrument='auto' "
                "for open-loop data"
            )
    ys = tuple(seg[out_name] for seg in segments)
    us = tuple(tuple(seg[n] for n in inputs) for seg in segments)
    rs = tuple(tuple(seg[n] for n in refs) for seg in segments)
    for label, arrays in (("output", ys), *((f"input {n!r}", [u[i] for u in us])
                                          for i, n in enumerate(inputs)),
                          *((f"reference {n!r}", [r[i] for r in rs]) for i, n in enumerate(refs))):
        check_magnitude(label, arrays)
    for k, name in enumerate(inputs):
        check_not_constant(name, [u[k] for u in us])
    for k, name in enumerate(refs):
        check_not_constant(name, [r[k] for r in rs])
    return SignalData(ys, us, rs, tuple(inputs), out_name, tuple(refs), first.dt)


def check_record(orders_label: str, n_par: int, data: SignalData, start: int,
                 longest_lag: int) -> int:
    """Number of equations, or a DataError naming the fix when there are too few."""
    n_rows = data.rows(start)
    longest = max(data.lengths)
    if longest_lag >= longest or n_rows <= n_par:
        need = max(start + n_par + 1, longest_lag + 1)
        raise DataError(
            f"{orders_label} has {n_par} parameters and delays up to {longest_lag} samples; it "
            f"needs at least {need} samples ({start} skipped + {n_par + 1} equations), got "
            f"{longest if len(data.y) == 1 else n_rows}. Use a longer record or lower orders"
        )
    return n_rows
