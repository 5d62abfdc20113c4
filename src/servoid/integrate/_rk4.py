"""The fixed-step RK4 step every simulator in servoid takes.

One step of the classical fourth-order Runge–Kutta scheme from ``(t, x)``
over ``h`` with the input ``w`` held::

    k1 = f(t, x),  k2 = f(t + h/2, x + h/2·k1),  k3 = f(t + h/2, x + h/2·k2),
    k4 = f(t + h, x + h·k3),       x⁺ = x + h/6·(k1 + 2·(k2 + k3) + k4)

followed by a post-step hook ``post(t + h, x⁺, x, w, ctx)`` that projects
the new state onto what the physics allows: an end stop (position held,
outward velocity zeroed), a stuck piston (velocity set to exactly zero), a
clamped level.  The hook sees the state before the step, so a velocity
that changed sign during the step is caught.

:func:`rk4_step` is compiled by numba into the caller's kernel (``inline``),
with ``rhs`` and ``post`` fixed at compile time: a plant's kernel is one
compiled function (cached on disk like every kernel of servoid) whose inner
loop is the same machine code as a hand-unrolled RK4.  The state is a
tuple of floats (a plant with a fixed number of states: the arithmetic is
unrolled, nothing is allocated) or a 1-D array (a user's ODE: the
arithmetic loops over it).  ``rhs`` may return more values than there are
states (outputs such as flows or forces computed on the way); the step uses
the first ``len(x)`` and hands the whole first-stage tuple back, so a
kernel can record them without a second evaluation.  The same function runs
as plain Python (``rk4_step.py_func``) for right-hand sides numba cannot
compile.
"""

from __future__ import annotations

import numba
import numpy as np
from numba import types
from numba.extending import overload

__all__ = ["advance", "keep", "rk4_step"]


@numba.njit(inline="always")
def rk4_step(rhs, post, t, x, w, ctx, h):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Return ``(post(t + h, x⁺, x, w, ctx), k1)``: one RK4 step and its first stage.

    ``rhs(t, x, w, ctx)`` returns the rates (and optionally more values
    after them); ``post`` returns the state to continue from (or anything
    the kernel wants back, such as a state and a flag).
    """
    half = 0.5 * h
    k1 = rhs(t, x, w, ctx)
    k2 = rhs(t + half, stage(x, half, k1), w, ctx)
    k3 = rhs(t + half, stage(x, half, k2), w, ctx)
    k4 = rhs(t + h, stage(x, h, k3), w, ctx)
    return post(t + h, combine(x, h / 6.0, k1, k2, k3, k4), x, w, ctx), k1


@numba.njit(cache=True, inline="always")
def keep(t, x_new, x_old, w, ctx):  # type: ignore[no-untyped-def]  # pragma: no cover
    """The post-step hook of an unconstrained system: the new state as it is."""
    return x_new


@numba.njit(inline="always")
def advance(rhs, post, t, x, w, ctx, h, steps):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Return the state after ``steps`` RK4 steps of ``h`` from ``(t, x)``, ``w`` held.

    For hooks that return the state (``keep`` or a projection).
    """
    for i in range(steps):
        x, _ = rk4_step(rhs, post, t + i * h, x, w, ctx, h)
    return x


def stage(x, s, k):  # type: ignore[no-untyped-def]
    """Return ``x + s·k`` over the states (``k`` may carry extra trailing values)."""
    if type(x) is tuple:
        return tuple([xi + s * ki for xi, ki in zip(x, k, strict=False)])
    if type(k) is not np.ndarray or k.shape != x.shape:
        k = np.asarray(k, dtype=float)[: x.size]
    return x + s * k


def combine(x, h6, k1, k2, k3, k4):  # type: ignore[no-untyped-def]
    """Return ``x + h6·(k1 + 2·(k2 + k3) + k4)`` over the states."""
    if type(x) is tuple:
        return tuple([xi + h6 * (a + 2.0 * (b + c) + d)
                      for xi, a, b, c, d in zip(x, k1, k2, k3, k4, strict=False)])
    a, b, c, d = (k if type(k) is np.ndarray and k.shape == x.shape
                  else np.asarray(k, dtype=float)[: x.size] for k in (k1, k2, k3, k4))
    return x + h6 * (a + 2.0 * (b + c) + d)


def _unrolled(name: str, args: str, term: str, n: int):  # type: ignore[no-untyped-def]
    """Compile-time source of a tuple operation unrolled over ``n`` states."""
    items = ", ".join(term.format(i=i) for i in range(n))
    namespace: dict[str, object] = {}
    exec(f"def {name}({args}):\n    return ({items},)\n", namespace)  # noqa: S102 — fixed text
    return namespace[name]


@overload(stage, inline="always")
def _stage_nb(x, s, k):  # type: ignore[no-untyped-def]
    if isinstance(x, types.BaseTuple):
        return _unrolled("impl", "x, s, k", "x[{i}] + s * k[{i}]", len(x))
    if isinstance(x, types.Array):
        def impl(x, s, k):  # type: ignore[no-untyped-def]  # pragma: no cover
            out = np.empty(x.size)
            for i in range(x.size):
                out[i] = x[i] + s * k[i]
            return out
        return impl
    return None


@overload(combine, inline="always")
def _combine_nb(x, h6, k1, k2, k3, k4):  # type: ignore[no-untyped-def]
    if isinstance(x, types.BaseTuple):
        return _unrolled("impl", "x, h6, k1, k2, k3, k4",
                         "x[{i}] + h6 * (k1[{i}] + 2.0 * (k2[{i}] + k3[{i}]) + k4[{i}])", len(x))
    if isinstance(x, types.Array):
        def impl(x, h6, k1, k2, k3, k4):  # type: ignore[no-untyped-def]  # pragma: no cover
            out = np.empty(x.size)
            for i in range(x.size):
                out[i] = x[i] + h6 * (k1[i] + 2.0 * (k2[i] + k3[i]) + k4[i])
            return out
        return impl
    return None
