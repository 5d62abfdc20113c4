"""Why the data reject the reduced model: the cause the evidence points to.

A rejection by the structure test (:mod:`._structure_test`) says the
reduced model is wrong, not why.  The richer linear structures absorb
whatever departs from it into their one extra parameter, so the
structure with the lowest BIC is not by itself the physical answer: a
nonlinearity shows up as a "valve lag" with a wrong δ_hp, a channel skew
as a shifted ω_hp.  The note weighs the evidence each check gives:

=====================  ====================================================  ==================
cause                  evidence                                              source
=====================  ====================================================  ==================
a nonlinearity         the flow law moves the parameters beyond their        :mod:`._flow_check`
                       intervals; or the residual depends on the reference
                       and no richer linear structure explains it
a saturated command    the flow law's signature and the DC gain off c/F      :mod:`._flow_check`,
                                                                             :mod:`._dc_gain`
a delay                ``reduced+skew`` explains the data best               the structure test
a missing dynamic      ``reduced+lag`` or ``full-order`` explains it best    the structure test
poor excitation        the fit's flags: the resonance not resolved or not    :mod:`._onestep`
                       determined by the data
=====================  ====================================================  ==================

and says which estimates to read: the preferred structure's (with their
intervals) for a delay or a missing dynamic, the flow-law values or the
nonlinear refinement for a nonlinearity.
"""

from __future__ import annotations

from typing import Any

from ._result import ClosedLoopResult
from ._structure_test import _seconds

__all__ = ["rejection_note"]

_LINEAR = {"reduced+skew": "a delay between the reference and the position channels",
           "reduced+lag": "a missing dynamic (a valve lag the reduced model leaves out)",
           "full-order": "a missing dynamic (the valve's dynamics the reduced model leaves out)"}


def rejection_note(test: Any, flow_law: Any, result: ClosedLoopResult,
                   dc_gain: Any = None) -> str:
    """Return the note for a rejected reduced model, naming the cause.

    Parameters
    ----------
    test : StructureTest
        The rejecting structure test.
    flow_law : FlowLawCheck or None
        The flow-law check of the same fit.
    result : ClosedLoopResult
        The reduced one-step fit (its flags).
    dc_gain : DcGainCheck, optional
        Its DC-gain check: a mismatch beside the flow law's signature
        points to a saturated command rather than the flow law.

    Returns
    -------
    str
        The note.
    """
    causes: list[str] = []
    read = ""
    lr_rejects = any(t.rejected for t in test.tests)
    if flow_law is not None and flow_law.biased:
        if flow_law.gamma > 0 and dc_gain is not None and dc_gain.mismatch:
            causes.append(f"a nonlinearity: a saturated valve command (the loop's gain falls at "
                          f"large commands, z = {flow_law.z:+.1f}, and its DC gain is off c/F, "
                          "which the flow law alone does not do)")
            read = ("no linear structure describes a saturated loop: lower the test amplitude "
                    "(`servoid excite --plant` gives the largest feasible one) or refine with "
                    "the nonlinear EHSA (`[identify] refine = true`)")
        elif flow_law.gamma > 0:
            causes.append(f"a nonlinearity: the valve's flow law (z = {flow_law.z:+.1f}; the "
                          f"load pressure reaches about {100 * flow_law.pressure_ratio:.2g} % of "
                          "the supply)")
            read = ("a richer linear structure takes the flow law up in its extra parameter, "
                    "so its numbers are not the physical ones either: read the flow-law values "
                    "(see the flow-law note) or refine with the nonlinear EHSA (`[identify] "
                    "refine = true`)")
        else:
            causes.append(f"a nonlinearity other than the valve's flow law (the residual follows "
                          f"|u|·ÿ with the opposite sign, z = {flow_law.z:+.1f}: friction, a "
                          "dead zone, a saturation)")
            read = ("a richer linear structure takes the nonlinearity up in its extra "
                    "parameter, so its numbers are not the physical ones either: refine with "
                    "the nonlinear EHSA (`[identify] refine = true`)")
    if lr_rejects and test.preferred in _LINEAR:
        extra = next((t for t in test.tests if t.larger == test.preferred), None)
        detail = ""
        if extra is not None and extra.extra:
            name, value = next(iter(extra.extra.items()))
            std = extra.extra_std.get(name, float("nan"))
            detail = f" ({name} = {_seconds(name, value)} ± {_seconds(name, std)})"
        causes.append(_LINEAR[test.preferred] + detail)
        if not read:
            pref = test.fit(test.preferred)
            values = ", ".join(
                f"{k} = {v:.5g} ± {pref.reduced_std.get(k, float('nan')):.2g}"
                for k, v in pref.reduced.items())
            read = f"read the {test.preferred} estimates: {values}"
            if test.preferred == "reduced+skew":
                read += ("; check the ADC's channel sequence (a multiplexed converter reads "
                         "the channels one after another) or a dead time in the reference path")
    if not lr_rejects and not causes:
        causes.append("a nonlinearity or dynamics outside the catalogue: the residual depends on "
                      "the reference, and no richer linear structure explains it")
        read = ("no linear alternative fits better; refine with the nonlinear EHSA (`[identify] "
                "refine = true`)")
    if result.flags:
        causes.append("poor excitation: " + "; ".join(result.flags))
    text = ("the reduced model is rejected by the data (structure test): its intervals "
            "understate the error. The evidence points to " + "; and ".join(causes))
    return text + (f". {read[0].upper()}{read[1:]}" if read else "")
