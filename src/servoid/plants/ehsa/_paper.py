"""Set A: the paper's identified EHSA model, decoded and checked.

[S1] prints (OCR, models-spec §1.2)::

    Eq. 13   Ĝ_simple = 9 900 135 / (s (s + 7104)(s + 6019))
    Eq. 14   Ĝ_at     = 9 900 135 / ((s + 7104)(s² + 60 s + 1224))

Static feedback only changes the constant term of the denominator:
closing ``gain/(s(s+a)(s+b))`` with gain F gives ``s(s+a)(s+b) + F·gain``,
so the s² coefficient of the closed loop must equal a + b.

*Literal reading.*  a + b = 7104 + 6019 = 13 123, but Eq. 14 has
7104 + 60 = 7164.  Closing with F = 1 leaves a real pole at −0.23 rad/s, with Eq. 14's
F = 0.8783 at −0.20 rad/s (time constant 4–5 s): impossible for
an actuator tracking a 60 Hz PRBS, and not the roots of Eq. 14
(−7104, −30 ± 18j).  The literal Eq. 13 is inconsistent with Eq. 14.

*Decoded reading (adopted).*  Read 6019 as 60.19, a decimal point lost in
OCR.  Then ``s(s + 7104)(s + 60.19) = s³ + 7164.19 s² + 427 590 s``, whose
s² coefficient matches Eq. 14 to 0.003 %.  Matching Eq. 14's constant
term, ``F·9 900 135 = 7104·1224``, gives F = 0.8783 with c = 1; the
closed-loop roots are −7104.17 and −30.01 ± 17.99j, Eq. 14 to four digits,
and the DC gain of Eq. 14 is 9 900 135/(7104·1224) = 1.139 = 1/F.

In the reduced form ``K_v/(s(s²/ω² + 2δs/ω + 1))`` the decoded Eq. 13 is
K_v = 23.15 1/s, formal ω_hp = √(7104·60.19) = 653.9 rad/s and
δ_hp = 5.48: over-damped, two real poles, as the paper remarks.  The
−7104 rad/s pole lies above the Nyquist frequency of the paper's 1 kHz
sampling (3142 rad/s) and is best read as an artefact of unresolvable
fast dynamics; the 60 rad/s pole is likelier valve, driver or sensor lag
than the hydraulic resonance (> 1 kHz for the unloaded piston, Set C).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..._errors import OptionTypeError
from ._linear import ReducedEhsa

__all__ = ["SET_A", "PaperConsistency", "PaperSetA", "paper_consistency"]

# Tolerance of E5 [rad/s]: the printed Eq. 14 roots carry two significant
# digits in 60 and 1224 (±0.5 in the last digit moves the pair by < 0.5).
_ROOT_TOL = 0.5
# A closed-loop pole slower than this [rad/s] cannot belong to an actuator
# that tracks a 60 Hz PRBS (time constant > 1 s).
_SLOW_POLE = 1.0


@dataclass(frozen=True)
class PaperSetA:
    """Printed numbers of [S1] Eq. 13 and 14, with decoded pole.

    Parameters
    ----------
    gain : float
        Numerator of Eq. 13 and 14 [1/s³]. [P] 9 900 135.
    pole_fast : float
        Fast pole of Eq. 13 and 14, at −pole_fast [rad/s]. [P] 7104.
    pole_slow : float
        Slow pole of Eq. 13 [rad/s]. [P*] 60.19 (printed "6019").
    pole_slow_literal : float
        The slow pole as printed [rad/s]. [P] 6019.
    eq14_s1 : float
        s¹ coefficient of Eq. 14's quadratic [rad/s]. [P] 60.
    eq14_s0 : float
        s⁰ coefficient of Eq. 14's quadratic [rad²/s²]. [P] 1224.
    c : float
        Reference gain [-]. [D] 1.
    dt : float
        Sample period of the paper's data [s]. [P] 1 ms.
    """

    gain: float = 9_900_135.0
    pole_fast: float = 7104.0
    pole_slow: float = 60.19
    pole_slow_literal: float = 6019.0
    eq14_s1: float = 60.0
    eq14_s0: float = 1224.0
    c: float = 1.0
    dt: float = 1e-3

    @property
    def F(self) -> float:
        """Feedback gain matching Eq. 14's constant term [-]."""
        return self.pole_fast * self.eq14_s0 / self.gain

    @property
    def model(self) -> ReducedEhsa:
        """Decoded Eq. 13 as a reduced plant."""
        return ReducedEhsa.from_real_poles(self.gain, self.pole_fast, self.pole_slow)

    def eq14_roots(self) -> NDArray[np.complex128]:
        """Return the roots of the printed Eq. 14 denominator."""
        den = np.polymul([1.0, self.pole_fast], [1.0, self.eq14_s1, self.eq14_s0])
        return _sorted(np.roots(den))

    def closed_loop_roots(self, pole_slow: float) -> NDArray[np.complex128]:
        """Return the roots of ``s(s+a)(s+b) + F·gain`` for b = pole_slow.

        Parameters
        ----------
        pole_slow : float
            The slow pole b [rad/s] to test.

        Returns
        -------
        ndarray of complex
            Closed-loop roots [rad/s], sorted by real part.
        """
        den = np.polymul([1.0, 0.0], np.polymul([1.0, self.pole_fast], [1.0, pole_slow]))
        den[-1] += self.F * self.gain
        return _sorted(np.roots(den))


#: Set A: paper replication, decoded Eq. 13 with c = 1 and F from Eq. 14.
SET_A = PaperSetA()


@dataclass(frozen=True)
class PaperConsistency:
    """Result of checking Eq. 13 against Eq. 14 (spec E5).

    Parameters
    ----------
    eq14_roots : ndarray of complex
        Roots of the printed Eq. 14 [rad/s].
    decoded_roots : ndarray of complex
        Closed-loop roots with the decoded 60.19 [rad/s].
    literal_roots : ndarray of complex
        Closed-loop roots with the literal 6019 [rad/s].
    decoded_error : float
        Largest distance of a decoded root from Eq. 14's [rad/s].
    literal_error : float
        Largest distance of a literal root from Eq. 14's [rad/s].
    decoded_consistent : bool
        Decoded roots within 0.5 rad/s of Eq. 14's.
    literal_consistent : bool
        Literal roots within 0.5 rad/s of Eq. 14's and no pole slower
        than 1 rad/s.
    literal_slow_pole : float
        The literal reading's slowest closed-loop pole [rad/s].
    F : float
        Feedback gain 7104·1224/9 900 135 [-].
    dc_gain : float
        DC gain of the decoded closed loop, c/F [-].
    K_v : float
        Velocity gain of decoded Eq. 13 [1/s].
    omega_hp : float
        Formal ω_hp = √(7104·60.19) [rad/s].
    delta_hp : float
        Formal δ_hp [-].
    explanation : str
        Why the literal reading fails and the decoded one holds.
    """

    eq14_roots: NDArray[np.complex128]
    decoded_roots: NDArray[np.complex128]
    literal_roots: NDArray[np.complex128]
    decoded_error: float
    literal_error: float
    decoded_consistent: bool
    literal_consistent: bool
    literal_slow_pole: float
    F: float
    dc_gain: float
    K_v: float
    omega_hp: float
    delta_hp: float
    explanation: str


def paper_consistency(paper: PaperSetA = SET_A) -> PaperConsistency:
    """Check the printed Eq. 13 against Eq. 14, both readings.

    Parameters
    ----------
    paper : PaperSetA
        The printed numbers (default :data:`SET_A`).

    Returns
    -------
    PaperConsistency
        Roots, errors, verdicts and the reduced-form parameters.
    """
    if not isinstance(paper, PaperSetA):
        raise OptionTypeError(f"paper must be PaperSetA, got {type(paper).__name__}")
    ref = paper.eq14_roots()
    decoded = paper.closed_loop_roots(paper.pole_slow)
    literal = paper.closed_loop_roots(paper.pole_slow_literal)
    err_d = _root_distance(decoded, ref)
    err_l = _root_distance(literal, ref)
    slow = float(np.min(np.abs(literal)))
    literal_ok = err_l <= _ROOT_TOL and slow >= _SLOW_POLE
    model = paper.model
    explanation = (
        f"Static feedback only changes the constant term, so the closed-loop s^2 "
        f"coefficient must equal a + b. Literal Eq. 13: a + b = "
        f"{paper.pole_fast + paper.pole_slow_literal:.0f}, Eq. 14: "
        f"{paper.pole_fast + paper.eq14_s1:.0f}; closing with F = {paper.F:.4f} leaves a pole "
        f"at {-slow:.3f} rad/s (time constant {1.0 / slow:.1f} s), impossible for an actuator "
        f"tracking a 60 Hz PRBS. Reading 6019 as {paper.pole_slow} (a decimal point lost in "
        f"OCR) reproduces Eq. 14 within {err_d:.3f} rad/s."
    )
    return PaperConsistency(
        eq14_roots=ref,
        decoded_roots=decoded,
        literal_roots=literal,
        decoded_error=err_d,
        literal_error=err_l,
        decoded_consistent=err_d <= _ROOT_TOL,
        literal_consistent=literal_ok,
        literal_slow_pole=-slow,
        F=paper.F,
        dc_gain=paper.c / paper.F,
        K_v=model.K,
        omega_hp=model.omega_hp,
        delta_hp=model.delta_hp,
        explanation=explanation,
    )


def _sorted(roots: NDArray) -> NDArray[np.complex128]:
    r = np.asarray(roots, dtype=np.complex128)
    return r[np.lexsort((r.imag, r.real))]


def _root_distance(roots: NDArray[np.complex128], ref: NDArray[np.complex128]) -> float:
    """Largest distance after matching each root to its nearest reference."""
    left = list(ref)
    worst = 0.0
    for r in roots:
        d = np.abs(np.asarray(left) - r)
        j = int(np.argmin(d))
        worst = max(worst, float(d[j]))
        left.pop(j)
    return worst
