"""``[identify] method = "ema"``: the EMA's method, as the registry sees it.

Light on purpose: the registry imports this module to list the method and
check its ``[identify]`` and ``[loop]`` keys; the run
(:mod:`._workflow_run`) and everything it needs load when it runs.

:data:`METHOD` is built on first access (PEP 562): building it needs
:class:`servoid.workflows.Method`, and the workflows' registry reads this
module's methods while it is itself being imported, so a top-level import
of the workflows here would be circular whenever this module is imported
first.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from ..._checks import as_float, as_int, as_mapping, as_str, type_error
from ..._errors import OptionError

__all__ = ["LOOP_KEYS", "METHOD", "METHODS", "controller_from_loop"]  # noqa: F822 - PEP 562

#: ``[loop]`` keys: the drive's gains (required) and its limits and sensors (optional).
LOOP_KEYS = {
    "kp_i": "current-loop gain [V/A]", "ki_i": "current-loop integral gain [V/(A·s)]",
    "kp_w": "speed-loop gain [A·s/rad]", "ki_w": "speed-loop integral gain [A/rad]",
    "kp_x": "position-loop gain [(rad/s)/m]",
    "ki_x": "position-loop integral gain [(rad/s)/(m·s)], default 0 (a P loop)",
    "u_max": "voltage limit [V], default none", "i_max": "current limit [A], default none",
    "w_max": "speed limit [rad/s], default none",
    "outer_every": "speed and position loops every this many samples, default 1",
    "encoder_counts": "encoder counts per motor revolution, default 0 (exact)",
    "feedback": "\"load\" (LVDT, default) or \"motor\" (encoder) position feedback",
}
_REQUIRED = ("kp_i", "ki_i", "kp_w", "ki_w", "kp_x")


def _channel_or_false(value: Any, where: str, name: str) -> str | None:
    if value is False:
        return None
    if not isinstance(value, str) or not value:
        raise type_error(name, value, "a channel name, or false for none", where=where)
    return value


def controller_from_loop(table: Mapping[str, Any]) -> Any:
    """The drive an experiment file's ``[loop]`` describes.

    Parameters
    ----------
    table : mapping
        The ``[loop]`` table (see :data:`LOOP_KEYS`): the five gains are
        required; a limit left out is no limit.

    Returns
    -------
    EmaController
        The loop.

    Raises
    ------
    OptionError
        An unknown or missing key (the message lists the valid ones).
    """
    from ._control import EmaController

    table = as_mapping("table", table, where="[loop]")
    unknown = sorted(set(table) - set(LOOP_KEYS))
    if unknown:
        raise OptionError(f"unknown key(s) in [loop]: {', '.join(unknown)}; valid keys for "
                          f"method = \"ema\" are {', '.join(LOOP_KEYS)}")
    missing = [k for k in _REQUIRED if k not in table]
    if missing:
        raise OptionError(f"[loop] needs {', '.join(missing)} (the drive's gains) to simulate "
                          f"the identified actuator in its loop; give them, or remove [loop] "
                          "to identify without the validation")
    values: dict[str, Any] = {}
    for key in ("kp_i", "ki_i", "kp_w", "ki_w", "kp_x", "ki_x"):
        if key in table:
            values[key] = as_float(key, table[key], nonneg=True, where="[loop]")
    for key in ("u_max", "i_max", "w_max"):
        values[key] = as_float(key, table.get(key, float("inf")), positive=True, finite=False,
                               where="[loop]")
    for key, low in (("outer_every", 1), ("encoder_counts", 0)):
        if key in table:
            values[key] = as_int(key, table[key], minimum=low, where="[loop]")
    if "feedback" in table:
        values["feedback"] = as_str("feedback", table["feedback"], where="[loop]")
    try:
        return EmaController(**values)
    except (ValueError, TypeError) as exc:
        raise OptionError(f"[loop]: {exc}") from None


def _run(spec: Any, options: Mapping[str, Any], truth: Mapping[str, Any] | None) -> Any:
    from ._workflow_run import run_ema

    return run_ema(spec, options, truth)


def _build() -> Any:
    from ...workflows._options import boolean, integer, number, optional, text
    from ...workflows._registry import Method, Option

    return Method(
        name="ema",
        summary="electromechanical actuator in its known drive ([loop] gains): motor constant, "
                "resistance, inductance, inertias, viscous and Coulomb friction and screw "
                "stiffness from a closed-loop record, with intervals; free-run validation",
        options=(
            Option("gear_ratio", None, optional(number(positive=True)),
                   "motor turns per screw turn (required)"),
            Option("lead", None, optional(number(positive=True, unit="m")),
                   "screw lead [m] (required)"),
            Option("current", "i_motor", text(), "motor current channel [A]"),
            Option("voltage", "u_cmd", _channel_or_false,
                   "voltage command channel [V], or false when not logged"),
            Option("angle", "theta_m", text(), "motor encoder channel [rad]"),
            Option("position", "x_load", text(), "load position channel (LVDT) [m]"),
            Option("reference", None, optional(text()),
                   "position reference channel; none: the r channel"),
            Option("motor_constant", None, optional(number(positive=True, unit="N·m/A")),
                   "known motor constant [N·m/A]; none: identified from the voltage"),
            Option("motor_constant_std", 0.0, number(nonneg=True),
                   "its standard deviation [N·m/A]"),
            Option("load_mass", None, optional(number(positive=True, unit="kg")),
                   "known load mass [kg]; none: identified from the screw's deflection"),
            Option("bandwidth", 30.0, number(positive=True, unit="Hz"),
                   "state-variable filter of the mechanical equations [Hz]"),
            Option("bandwidth_electrical", 150.0, number(positive=True, unit="Hz"),
                   "state-variable filter of the electrical equation [Hz]"),
            Option("order", 4, integer(minimum=4, maximum=8), "filter order"),
            Option("row_step", None, optional(integer(minimum=1)),
                   "rows every this many samples; none: 8 per period of bandwidth_electrical"),
            Option("min_speed", None, optional(number(positive=True, unit="m/s")),
                   "slower nut motion is left out [m/s]; none: 5 % of the rms speed"),
            Option("max_relative_std", 0.25, number(positive=True),
                   "larger relative std: not identifiable from this record"),
            Option("min_deflection_fit", 85.0, number(unit="%"),
                   "least fit [%] of the deflection equation for the load side, the split "
                   "and k_s"),
            Option("validate", True, boolean(),
                   "simulate the identified actuator in its loop on held-back data (needs [loop])"),
        ),
        run=_run,
        tables=("loop", "validation"),
    )


def __getattr__(name: str) -> Any:
    # METHOD: the method; METHODS: the plant's methods, for its Plant record
    if name not in ("METHOD", "METHODS"):
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    if "METHOD" not in globals():
        method = _build()
        # building imports the workflows, whose registry may have built it meanwhile
        globals().setdefault("METHOD", method)
        globals()["METHODS"] = (globals()["METHOD"],)
    return globals()[name]
