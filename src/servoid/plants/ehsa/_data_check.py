"""What an EHSA record cannot fix, said before the one-step intervals.

:func:`servoid.validate.data_limits` looks at the reference and the
position for a step, one sine, drift and clipped samples.  For the
one-step fit of (K, ω_hp, δ_hp) inside the known loop this module adds
what a single sine means for those three numbers: a sine at ω₀ fixes the
loop's gain and phase there, ``|H(jω₀)|`` and ``∠H(jω₀)`` of
``H = c·G/(1 + F·G)``, two numbers for three parameters.  The Jacobian J
of ``(ln|H|, ∠H)`` with respect to ``(ln K, ln ω_hp, δ_hp)`` at the
estimate (central differences) has a null vector n: moving the
parameters along n leaves what the sine shows unchanged, so that
combination rests on the model's structure and on the noise, not on the
data.  The note names n and the two fixed numbers.

A saturated valve command (a driver at its limit) is seen by the
higher-order correlation tests of the validation, by the flow-law check
(the loop's gain falls at large commands, as with the flow law) and, unlike
the flow law, by the DC-gain check: the loop's integrator keeps the DC
gain at c/F under the flow law (the flow-law study: 1–2 % mismatches, the
level), while a command clipped at about its rms pulls the fitted DC gain
off c/F (``benchmarks/bench_ehsa_validity.py``).  :func:`saturation_note`
says so when both checks fire.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ...data import as_segments
from ...validate import data_limits
from ._loop import FeedbackLoop, plant_of_theta
from ._result import ClosedLoopResult

__all__ = ["nonlinear_wanted", "one_sine_combination", "record_notes", "saturation_note"]


def record_notes(data: Any, result: ClosedLoopResult | None,
                 loop: FeedbackLoop) -> list[str]:
    """The data limits of an EHSA record, with a single sine's meaning for K, ω_hp, δ_hp.

    Parameters
    ----------
    data : Experiment or ExperimentSet
        The estimation record (reference r, position y).
    result : ClosedLoopResult or None
        The one-step fit, for the combination a sine leaves free.
    loop : FeedbackLoop
        The known loop.

    Returns
    -------
    list of str
        One note per limit found; empty when the record can fix the model.
    """
    segments = as_segments(data)
    first = segments[0]
    excitation = next(iter(first.names_of("r")), None)
    if excitation is None:
        return []
    outputs = list(first.names_of("y"))
    notes = []
    for limit in data_limits(data, excitation=excitation, outputs=outputs, inputs=[]):
        text = f"data cannot fix: {limit.text()}"
        if limit.name == "one sine" and result is not None and loop.is_static:
            f0 = _peak_hz(segments[0].channel(excitation).values, first.dt)
            text += ". " + one_sine_combination(result.estimate.parameters, loop, f0)
        notes.append(text)
    return notes


def one_sine_combination(theta: Any, loop: FeedbackLoop, f0: float) -> str:
    """Say which combination of K, ω_hp, δ_hp a sine at `f0` leaves free.

    Parameters
    ----------
    theta : array_like
        K [1/s], ω_hp [rad/s], δ_hp [-].
    loop : FeedbackLoop
        The known loop (static F).
    f0 : float
        The sine's frequency [Hz].

    Returns
    -------
    str
        The two numbers the sine fixes and the free direction.
    """
    k, w, d = (float(x) for x in theta[:3])
    w0 = 2.0 * math.pi * f0

    def gain_phase(x: np.ndarray) -> np.ndarray:
        h = complex(loop.close(plant_of_theta((math.exp(x[0]), math.exp(x[1]), x[2])))
                    .freqresp(np.array([w0]))[0])
        return np.array([math.log(abs(h)), math.atan2(h.imag, h.real)])

    x0 = np.array([math.log(k), math.log(w), d])
    steps = np.array([1e-6, 1e-6, 1e-6 * max(abs(d), 1e-3)])
    jac = np.column_stack([(gain_phase(x0 + e) - gain_phase(x0 - e)) / (2.0 * s)
                           for e, s in zip(np.diag(steps), steps, strict=True)])
    _, _, vt = np.linalg.svd(jac)
    null = vt[-1] / np.max(np.abs(vt[-1]))
    g, phi = gain_phase(x0)
    return (f"one sine at {f0:.4g} Hz fixes two numbers, the loop's gain and phase there "
            f"(|H| = {math.exp(g):.4g}, ∠H = {math.degrees(phi):.4g}°); K, omega_hp and "
            f"delta_hp can move together along d(ln K) : d(ln omega_hp) : d(delta_hp) = "
            f"{null[0]:+.3g} : {null[1]:+.3g} : {null[2]:+.3g} without changing them, so that "
            "combination rests on the model's structure and the noise, not on the data")


def saturation_note(flow_law: Any, dc_gain: Any) -> str:
    """A note when the flow-law and DC-gain checks both fire: a saturated command.

    Parameters
    ----------
    flow_law : FlowLawCheck or None
        The flow-law check of the one-step fit.
    dc_gain : DcGainCheck or None
        The DC-gain check.

    Returns
    -------
    str
        Empty unless both fire.
    """
    if flow_law is None or dc_gain is None or not (flow_law.biased and dc_gain.mismatch):
        return ""
    return ("the loop's gain falls at large commands (flow-law check) and its DC gain is off "
            "c/F (DC-gain check): the flow law alone keeps the DC gain at c/F, so the valve "
            "command is likely saturated (a driver or valve at its limit, a clipped input). "
            "The linear intervals do not hold on such data: lower the test amplitude "
            "(`servoid excite` gives the largest feasible one) or check the driver's limit")


def _peak_hz(r: np.ndarray, dt: float) -> float:
    x = np.asarray(r, dtype=float) - float(np.mean(r))
    spec = np.abs(np.fft.rfft(x * np.hanning(x.size)))
    freqs = np.fft.rfftfreq(x.size, dt)
    return float(freqs[int(np.argmax(spec[1:])) + 1])


def nonlinear_wanted(flow_law: Any, dc_gain: Any, validation: Any) -> tuple[bool, str]:
    """Decide ``structure = "auto"``: refine with the nonlinear EHSA, or keep the linear fit.

    The nonlinear refinement runs when a check says the linear model
    misses a nonlinearity the nonlinear EHSA holds: the flow-law check
    (the loop's gain moves with the load pressure beyond the intervals),
    the flow-law and DC-gain checks together (a saturated command), or the
    higher-order correlation tests of the validation.

    Parameters
    ----------
    flow_law : FlowLawCheck or None
        The flow-law check of the one-step fit.
    dc_gain : DcGainCheck or None
        Its DC-gain check.
    validation : ValidationReport or None
        The primary result's validation.

    Returns
    -------
    run : bool
        True to run the nonlinear refinement.
    why : str
        The note saying which model was used and why.
    """
    why = []
    if flow_law is not None and flow_law.biased:
        why.append(f"the flow-law check fired (z = {flow_law.z:+.1f})")
    if saturation_note(flow_law, dc_gain):
        why.append("the DC gain is off c/F (a saturated command)")
    nonlinearity = getattr(validation, "nonlinearity", None)
    if nonlinearity is not None and nonlinearity.detected:
        why.append(f"the higher-order correlation tests found a nonlinearity the linear model "
                   f"leaves (p = {nonlinearity.pvalue:.2g})")
    if why:
        return True, ("structure = auto: " + "; ".join(why) + ", so the nonlinear EHSA "
                      "refinement ran; read its estimates (nonlinear refinement)")
    return False, ("structure = auto: no check found a nonlinearity (flow law, DC gain, "
                   "higher-order correlation tests), so the linear model stands and the "
                   "nonlinear refinement did not run")
