"""The multi-step scheme S0–S6 as one pipeline ([S2] Fig. 17).

Hahn & Piepenbrink (IFAC SYSID 1994) identify the servopneumatic model
equation group by equation group, each from the test that excites it,
inserting earlier estimates into later equations (models-spec §3.9):

====  ==========  =====================================================
step  record      what
====  ==========  =====================================================
S0    flow        p_krit by separable LS (Type IV → Type II)
S0    friction    ẋ_krit from the friction–velocity map
S1    valve       k_v, ξ_v, ω_v: SVF + LS on (1)
S2    thermo      κ, R: SVF + RLS/LS on the derivative-free (2.x)
S3    flow        a_i d_i: LS per edge on (3.x) with κ, R, p_krit
S4    friction    d_k, c_k: LS on (4.1), |ẋ_k| ≥ ẋ_krit
S5    friction    F_haft: LS on (4.2) with c_k, d_k inserted
S6    validation  simulate the full model on held-back data
====  ==========  =====================================================

Optionally the assembled set is refined by grey-box output error on an
estimation record (:func:`refine_parameters`) and validated again.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..._checks import as_bool, as_float, as_instance, as_int, as_str_list, type_error
from ..._errors import ChannelError, DataError, IdentifiabilityError, ServoidWarning, check_option
from ..._progress import stage
from ..._warn import warn
from ...data import Experiment
from ...estimate import GREYBOX_COVARIANCES, GreyboxCovariance, Hold
from ._params import PneumaticParameters
from ._refine import (
    REFINABLE,
    UNITS,
    RecordComparison,
    RefinementResult,
    compare_record,
    refine_parameters,
)
from ._sim import PositionController
from ._step_flow import identify_critical_pressure, identify_flow
from ._step_friction import (
    identify_critical_velocity,
    identify_low_speed_friction,
    identify_sliding_friction,
)
from ._step_thermo import identify_thermodynamics
from ._step_valve import identify_valve
from ._steps import (
    MDOT_LIMIT,
    Derivatives,
    KnownConstants,
    StepResult,
    check_derivatives,
    check_known,
    check_positive,
)

__all__ = ["RECORDS", "MultistepResult", "identify_multistep"]

#: Where every ± comes from, as the console and the report say it.
STD_SOURCES = ("1σ statistical: instrumental variables in S0 p_krit, S1, S3, S4 (they carry the "
               "regressors' noise), least squares in S2, S5 (Newey–West covariance in S0 p_krit "
               "and S2–S5, where the rig's coloured noise matters), plus the propagated std of "
               "inserted estimates (delta method); v_krit by a moving-block bootstrap of its "
               "threshold search")

#: Records the pipeline needs, by test name.
RECORDS: tuple[str, ...] = ("valve", "thermo", "flow", "friction", "validation")


@dataclass(frozen=True, eq=False)
class MultistepResult:
    """Every step of S0–S6, the parameters and the validation.

    Attributes
    ----------
    steps : mapping of str to StepResult
        In order: "S0 p_krit", "S0 ẋ_krit", "S1", "S2", "S3", "S4", "S5"
        (a given p_krit or ẋ_krit has no step).
    parameters : PneumaticParameters
        The assembled set (multi-step estimates + known constants).
    known : KnownConstants
        The constants taken as known.
    validation : RecordComparison
        Step S6 with the multi-step set.
    derivatives : str
        "measured" or "svf".
    refinement : RefinementResult or None
        The grey-box refinement, when asked for.
    refined_validation : RecordComparison or None
        Step S6 with the refined set.
    given : mapping of str to float
        Parameters given instead of identified (p_krit, v_krit).
    notes : tuple of str
        Warnings of the steps, collected.
    """

    steps: Mapping[str, StepResult]
    parameters: PneumaticParameters
    known: KnownConstants
    validation: RecordComparison
    derivatives: str
    refinement: RefinementResult | None = None
    refined_validation: RecordComparison | None = None
    given: Mapping[str, float] = field(default_factory=dict)
    notes: tuple[str, ...] = ()

    def std(self, name: str) -> float:
        """Std of an identified parameter from its step.

        Parameters
        ----------
        name : str
            A name of :data:`REFINABLE`.

        Returns
        -------
        float
            Its standard deviation (0 for a given value).
        """
        for step in self.steps.values():
            if name in step.estimate.names:
                return step.std(name)
        if name in self.given:
            return 0.0
        raise ChannelError(f"no identified parameter {name!r}; they are "
                           f"{', '.join(REFINABLE)}")

    def table(self) -> list[dict[str, Any]]:
        """Per parameter: value, std, 95 % CI, unit, the step and the std's kind.

        ``std_kind`` is "statistical" (every identified parameter: LS or, in
        S0 p_krit, S1, S3 and S4, instrumental variables, with a Newey–West
        covariance in S0 p_krit and S2–S5, plus the inserted estimates' std propagated,
        v_krit by a block bootstrap) or "given" (std 0).
        """
        rows = []
        for name in REFINABLE:
            step_of = next((s for s in self.steps.values() if name in s.estimate.names), None)
            if step_of is None:
                value = float(self.given.get(name, getattr(self.parameters, name)))
                rows.append({"name": name, "value": value, "std": 0.0, "ci95": [value, value],
                             "unit": UNITS[name], "step": "given", "std_kind": "given"})
                continue
            row = next(r for r in step_of.estimate.table() if r.name == name)
            rows.append({"name": name, "value": row.value, "std": row.std,
                         "ci95": [row.ci_low, row.ci_high], "unit": UNITS[name],
                         "step": step_of.step, "std_kind": "statistical"})
        return rows

    @property
    def final_parameters(self) -> PneumaticParameters:
        """The refined set if refined, else the multi-step set."""
        return self.refinement.parameters if self.refinement else self.parameters

    def to_dict(self) -> dict[str, Any]:
        """Plain data for JSON."""
        return {
            "derivatives": self.derivatives,
            "known": self.known.to_dict(),
            "given": dict(self.given),
            "parameters": self.table(),
            "steps": {k: s.to_dict() for k, s in self.steps.items()},
            "validation": self.validation.to_dict(),
            "refinement": None if self.refinement is None else self.refinement.to_dict(),
            "refined_validation": None if self.refined_validation is None else
            self.refined_validation.to_dict(),
            "notes": list(self.notes),
        }

    def __str__(self) -> str:
        lines = [f"multi-step identification (S0–S6, derivatives {self.derivatives!r})"]
        for row in self.table():
            lines.append(f"  {row['name']:<8} {row['value']: .6g} ± {row['std']:.2g} "
                         f"{row['unit']:<9} ({row['step']})")
        fits = ", ".join(f"{k} {v:.1f} %" for k, v in self.validation.fit.items())
        lines.append(f"  S6 validation fit ({self.validation.record}): {fits}")
        if self.refined_validation is not None:
            fits = ", ".join(f"{k} {v:.1f} %" for k, v in self.refined_validation.fit.items())
            lines.append(f"  after refinement: {fits}")
        lines.append(f"  ± are {STD_SOURCES}")
        lines += [f"  note: {n}" for n in self.notes]
        return "\n".join(lines)


def identify_multistep(
    records: Mapping[str, Experiment],
    known: KnownConstants,
    *,
    derivatives: Derivatives = "svf",
    refine: bool | Sequence[str] = False,
    refine_record: str = "thermo",
    controller: PositionController | None = None,
    p_krit: float | None = None,
    v_krit: float | None = None,
    blend: bool = False,
    mdot_limit: float = MDOT_LIMIT,
    valve_omega_f: float = 2 * math.pi * 300.0,
    valve_u_hold: Hold = "zoh",
    thermo_omega_f: float = 2 * math.pi * 30.0,
    friction_omega_f: float = 2 * math.pi * 400.0,
    refine_max_nfev: int | None = None,
    refine_covariance: GreyboxCovariance = "auto",
    rng: np.random.Generator | int | None = None,
) -> MultistepResult:
    """Identify the servopneumatic model step by step (S0–S6).

    Parameters
    ----------
    records : mapping of str to Experiment
        The tests by name: "valve" (rectangular u, S1), "thermo"
        (closed-loop sine + rectangular external force, S2), "flow"
        (closed-loop sine with |ṁ| within the sensor range, S0 p_krit,
        S3), "friction" (rectangular input, S0 ẋ_krit, S4, S5) and
        "validation" (a held-back record, S6).  One Experiment may serve
        several tests.  Channels (SI): u, x_ref, x_k, x_v, p_I, p_II,
        T_I, T_II, mdot_I, mdot_II, v_k, a_k, f_ext.
    known : KnownConstants
        Geometry, mass, supply and gravity.
    derivatives : {"svf", "measured"}
        "measured": piston velocity and acceleration from the ``v_k``,
        ``a_k`` channels; "svf": state-variable filters on x_k (the
        paper's way).  The valve (S1) and the chamber equations (S2)
        always use SVFs for ẋ_v, ẍ_v and d(Vp)/dt, which are not sensed.
    refine : bool or sequence of str
        After S5, refine all identified parameters (True) or the named
        subset by grey-box output error on ``records[refine_record]``.
    refine_record : str
        Record for the refinement (an estimation record, not "validation").
    controller : PositionController, optional
        The loop's controller for closed-loop simulations; None
        reconstructs it from each record's u, x_ref, x_k, v_k.
    p_krit : float, optional
        Known critical pressure ratio: skips the S0 search.
    v_krit : float, optional
        Known friction threshold [m/s]: skips the S0 map.
    blend : bool
        Use the blended low-speed friction law in S5 (S6 simulates the
        constant-F_haft law of the simulator's default).
    mdot_limit : float
        Mass-flow sensor range [kg/s].
    valve_omega_f, thermo_omega_f, friction_omega_f : float
        SVF bandwidths of S1, S2 and of the friction steps [rad/s].
    valve_u_hold : {"zoh", "cubic", "foh", "tustin"}
        Inter-sample course of u in S1 (:func:`identify_valve`): "zoh"
        for the DAC's staircase as commanded, "cubic" when the recorded u
        passed the rig's anti-alias filter like the other channels (then
        it is no staircase: "zoh" biases ω_v by +1.3 % at 10 kHz).
    refine_max_nfev : int, optional
        Limit on simulations of the refinement.
    refine_covariance : {"auto", "white", "robust", "bootstrap"}
        Covariance of the refined parameters (:func:`refine_parameters`).
    rng : numpy.random.Generator or int, optional
        Source of the refinement's bootstrap resamples.

    Returns
    -------
    MultistepResult
        Steps, assembled parameters, S6 validation (and refinement).

    Raises
    ------
    DataError
        A record is missing or a channel is unusable.
    IdentifiabilityError
        A step cannot determine its parameters (e.g. a flow edge).
    """
    check_derivatives(derivatives)
    check_option("refine_covariance", refine_covariance, GREYBOX_COVARIANCES)
    known = check_known(known)
    if not isinstance(records, Mapping):
        raise type_error("records", records, "a mapping {test name: Experiment} with the "
                         f"records {', '.join(RECORDS)}")
    missing = [r for r in RECORDS if r not in records]
    if missing:
        raise DataError(f"the multi-step scheme needs the records {', '.join(RECORDS)}; "
                        f"missing: {', '.join(missing)}")
    for key, rec in records.items():
        if not isinstance(rec, Experiment):
            raise type_error(f"records[{key!r}]", rec, "an Experiment")
    if controller is not None:
        as_instance("controller", controller, PositionController,
                    "a PositionController(K_p, K_d) or None")
    if p_krit is not None:
        p_krit = as_float("p_krit", p_krit)
        if not 0.0 <= p_krit < 1.0:  # checked here, not after the first steps in S3
            raise DataError(f"p_krit must lie in [0, 1) (a pressure ratio), got {p_krit:g}")
    if v_krit is not None:
        v_krit = check_positive("v_krit", v_krit, "m/s")
    blend = as_bool("blend", blend)
    if refine_max_nfev is not None:
        refine_max_nfev = as_int("refine_max_nfev", refine_max_nfev, minimum=1)
    if refine is not False and refine is not True:
        refine = as_str_list("refine", refine, min_length=1)
        check_option("refine_record", refine_record, tuple(k for k in records
                                                           if k != "validation"))
    steps: dict[str, StepResult] = {}
    given: dict[str, float] = {}
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ServoidWarning)
        if p_krit is None:
            steps["S0 p_krit"] = identify_critical_pressure(records["flow"], known,
                                                            mdot_limit=mdot_limit)
            b = steps["S0 p_krit"]["p_krit"]
            b_std = steps["S0 p_krit"].std("p_krit")
        else:
            b_std = 0.0
            b = given["p_krit"] = float(p_krit)
        if v_krit is None:
            steps["S0 ẋ_krit"] = identify_critical_velocity(
                records["friction"], known, derivatives=derivatives, omega_f=friction_omega_f)
            vk = steps["S0 ẋ_krit"]["v_krit"]
            vk_std = steps["S0 ẋ_krit"].std("v_krit")
        else:
            vk_std = 0.0
            vk = given["v_krit"] = float(v_krit)
        steps["S1"] = identify_valve(records["valve"], omega_f=valve_omega_f,
                                     u_hold=valve_u_hold)
        s2 = steps["S2"] = identify_thermodynamics(records["thermo"], known,
                                                   derivatives=derivatives,
                                                   omega_f=thermo_omega_f, mdot_limit=mdot_limit)
        steps["S3"] = identify_flow(records["flow"], known, kappa=s2["kappa"], R=s2["R"],
                                    p_krit=b, kappa_std=s2.std("kappa"), R_std=s2.std("R"),
                                    p_krit_std=b_std,
                                    mdot_limit=mdot_limit)
        s4 = steps["S4"] = identify_sliding_friction(records["friction"], known, v_krit=vk,
                                                     v_krit_std=vk_std, derivatives=derivatives,
                                                     omega_f=friction_omega_f)
        steps["S5"] = identify_low_speed_friction(
            records["friction"], known, v_krit=vk, d_k=s4["d_k"], c_k=s4["c_k"],
            v_krit_std=vk_std, sliding_covariance=s4.estimate.covariance,
            derivatives=derivatives, blend=blend, omega_f=friction_omega_f)
    notes = [str(w.message) for w in caught if issubclass(w.category, ServoidWarning)]
    for w in caught:  # re-issue so callers see them too
        warn(w.message, w.category)
    values = _assemble(steps, given)
    params = known.to_parameters(**values)
    with stage("S6: simulating the multi-step model on the validation record"):
        validation = compare_record(params, records["validation"], controller,
                                    mdot_limit=mdot_limit, name="validation")
    refinement = refined_validation = None
    if refine is not False:
        free = None if refine is True else list(refine)
        with stage(f"refining the parameters by simulation error on the {refine_record!r} "
                   "record"):
            refinement = refine_parameters(records[refine_record], params, free=free,
                                           controller=controller, max_nfev=refine_max_nfev,
                                           name=refine_record, covariance=refine_covariance,
                                           rng=rng)
        with stage("S6: simulating the refined model on the validation record"):
            refined_validation = compare_record(refinement.parameters, records["validation"],
                                                controller, mdot_limit=mdot_limit,
                                                name="validation")
    return MultistepResult(steps, params, known, validation, derivatives, refinement,
                           refined_validation, given, tuple(dict.fromkeys(notes)))


def _assemble(steps: Mapping[str, StepResult], given: Mapping[str, float]) -> dict[str, float]:
    values: dict[str, float] = dict(given)
    for step in steps.values():
        if step.step == "S0 p_krit":
            values["p_krit"] = step["p_krit"]  # the lumped c_i are placeholders, not a_i d_i
            continue
        values.update(step.values)
    lacking = [n for n in REFINABLE if n not in values]
    if lacking:
        raise IdentifiabilityError(
            f"the model cannot be assembled: {', '.join(lacking)} not identified (see the "
            "step notes); give records that excite them"
        )
    return {n: values[n] for n in REFINABLE}

