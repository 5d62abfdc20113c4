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

from ..._checks import as_float, as_int, as_str, type_error
from ..._errors import OptionError

__all__ = ["LOOP", "LOOP_KEYS", "METHOD", "METHODS", "controller_from_loop",  # noqa: F822
           "drive"]  # LOOP, METHOD, METHODS: PEP 562

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
    return drive(_loop().parse(table, "ema"))


def drive(loop: Mapping[str, Any]) -> Any:
    """The drive of a checked ``[loop]`` (every key of :data:`LOOP_KEYS`, None where absent)."""
    from ._control import EmaController

    missing = [k for k in _REQUIRED if loop[k] is None]
    if missing:
        raise OptionError(f"[loop] needs {', '.join(missing)} (the drive's gains) to simulate "
                          f"the identified actuator in its loop; give them, or remove [loop] "
                          "to identify without the validation")
    try:
        return EmaController(**{k: v for k, v in loop.items() if v is not None})
    except (ValueError, TypeError) as exc:
        raise OptionError(f"[loop]: {exc}") from None


def _gain(value: Any, where: str, name: str) -> float:
    return as_float(name, value, nonneg=True, where=where)


def _limit(value: Any, where: str, name: str) -> float:
    return as_float(name, value, positive=True, finite=False, where=where)


def _count(minimum: int) -> Any:
    def check(value: Any, where: str, name: str) -> int:
        return as_int(name, value, minimum=minimum, where=where)
    return check


def _text(value: Any, where: str, name: str) -> str:
    return as_str(name, value, where=where)


def _loop() -> Any:
    """The ``[loop]`` schema (built on first use, like :data:`METHOD`)."""
    if "LOOP" not in globals():
        from ...workflows._registry import Option, TableSchema

        checks = {"u_max": _limit, "i_max": _limit, "w_max": _limit,
                  "outer_every": _count(1), "encoder_counts": _count(0), "feedback": _text}
        infinite = ("u_max", "i_max", "w_max")
        globals()["LOOP"] = TableSchema("loop", tuple(
            Option(key, float("inf") if key in infinite else None, checks.get(key, _gain),
                   help + (" (required)" if key in _REQUIRED else ""))
            for key, help in LOOP_KEYS.items()), help="the drive: its gains, limits and sensors")
    return globals()["LOOP"]


def _run(spec: Any, options: Mapping[str, Any], truth: Mapping[str, Any] | None) -> Any:
    from ._workflow_run import run_ema

    return run_ema(spec, options, truth)


def _example(folder: Any, seed: int = 0) -> Any:
    from ._workflow_run import example

    return example(folder, seed)


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
        tables=(_loop(), "validation"),
        example=_example,
    )


def __getattr__(name: str) -> Any:
    # METHOD: the method; METHODS: the plant's methods, for its Plant record; LOOP: [loop]
    if name == "LOOP":
        return _loop()
    if name not in ("METHOD", "METHODS"):
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    if "METHOD" not in globals():
        method = _build()
        # building imports the workflows, whose registry may have built it meanwhile
        globals().setdefault("METHOD", method)
        globals()["METHODS"] = (globals()["METHOD"],)
    return globals()[name]
