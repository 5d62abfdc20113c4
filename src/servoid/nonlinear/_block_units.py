"""Units of a block model's parameters, from its channels' units.

The scale convention of :mod:`servoid.nonlinear._block_fit` decides where
the units go: a unit-slope shape passes its input's unit on, a free-scale
shape takes the unit of the linear block's far side, whose static gain is
then a pure number.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from ._block_linear import LinearBlock
from ._static import StaticNonlinearity

__all__ = ["parameter_units"]


def parameter_units(f: StaticNonlinearity | None, g: StaticNonlinearity | None,
                    lin: LinearBlock, offset: bool, names: Mapping[str, Any]) -> tuple[str, ...]:
    """Each parameter's unit from the channels' units and the scale convention.

    Unit-slope shapes pass their input's unit on; a free-scale shape takes
    the unit of the linear block's other side (whose static gain is then
    1, a pure number).  So v (the linear block's input) is in the input's
    unit unless f has the free scale, and x (its output) in the output's
    unit unless g has it.
    """
    u_unit, y_unit = names.get("input_unit", ""), names.get("output_unit", "")
    f_free = f is not None and f.free_scale
    g_free = g is not None and g.free_scale
    v_unit = y_unit if f_free else u_unit
    x_unit = u_unit if g_free else y_unit
    gain = "" if lin.unit_gain else _ratio(x_unit, v_unit)
    out: list[str] = []
    if f is not None:
        out += _shape_units(f, u_unit, v_unit)
    out += _linear_units(lin, gain)
    if g is not None:
        out += _shape_units(g, x_unit, y_unit)
    if offset:
        out.append(y_unit)
    return tuple(out)


def _shape_units(shape: StaticNonlinearity, x: str, y: str) -> list[str]:
    """Units of a shape's parameters, its input in ``x`` and output in ``y``."""
    n = shape.parameters.size
    if shape.kind in ("deadzone", "saturation", "abs"):  # breakpoints, centre: input's unit
        return [x] * n
    if shape.kind == "polynomial":  # c_k·x^k is in y
        return [_ratio(y, _power(x, k)) for k in range(1, n + 1)]
    if shape.kind == "piecewise-linear":  # slopes
        return [_ratio(y, x)] * n
    return [""] * n  # the exponent of a power; a user function's own parameters


def _linear_units(lin: LinearBlock, gain: str) -> list[str]:
    """Units of the linear block's parameters when its static gain has unit ``gain``."""
    if lin.kind == "oe":  # G(1) = Σb/F(1) with F monic: b in the gain's unit, f pure numbers
        return [gain if name.startswith("b") else "" for name in lin.names]
    # (b_m s^m + … + b0)/(s^n + a1 s^(n−1) + … + an): a_i in s^−i, b_j in gain·s^(j−n)
    n = lin.n_poles
    out = []
    for name in lin.names:
        k = int(name[1:])
        if name.startswith("a"):
            out.append(_per_second(k))
        else:
            out.append(_ratio(gain, _power("s", n - k)) if gain else _per_second(n - k))
    return out


def _power(unit: str, k: int) -> str:
    if not unit or k == 0:
        return "" if k == 0 or not unit else unit
    if k == 1:
        return unit
    wrapped = f"({unit})" if any(c in unit for c in "/·*") else unit
    return f"{wrapped}^{k}"


def _per_second(k: int) -> str:
    return "" if k == 0 else "1/" + _power("s", k)


def _ratio(top: str, bottom: str) -> str:
    if not bottom:
        return top
    wrapped = f"({bottom})" if any(c in bottom for c in "/·*") else bottom
    return f"{top or '1'}/{wrapped}"
