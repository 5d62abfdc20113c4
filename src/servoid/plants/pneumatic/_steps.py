"""Known constants, step results and helpers shared by the steps.

Every step of the multi-step scheme (Hahn & Piepenbrink, IFAC SYSID 1994,
[S2] Fig. 17; models-spec §3.9) returns a :class:`StepResult`: the
physical estimates with their covariance (an
:class:`~servoid.estimate.Estimate`), the record and the sample mask it
used, and the equation it solved in words.  The constants the scheme
takes as known (geometry, masses, supply) are a :class:`KnownConstants`.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from ..._checks import as_instance, as_mapping, type_error
from ..._errors import ChannelError, DataError, ModelError, OptionError, check_option
from ...data import Experiment
from ...estimate import Estimate, state_variable_filter
from ._params import PneumaticParameters

__all__ = [
    "DERIVATIVES",
    "MDOT_LIMIT",
    "Derivatives",
    "KnownConstants",
    "StepResult",
]

#: How derivatives of measured signals are obtained (see :func:`identify_multistep`).
Derivatives = Literal["measured", "svf"]
DERIVATIVES: tuple[str, ...] = ("measured", "svf")

#: Range of the paper's hot-wire mass-flow sensor [kg/s] ([S2] §4.2: 4 g/s).
MDOT_LIMIT = 4e-3

_KNOWN_UNITS = {
    "A_I": "m²", "A_II": "m²", "V_0I": "m³", "V_0II": "m³", "m_k": "kg", "p_S": "Pa",
    "p_R": "Pa", "p_amb": "Pa", "T_S": "K", "g": "m/s²", "stroke": "m", "u_max": "V",
    "eps_v": "m/s", "mdot_sensor_bandwidth": "Hz",
}
#: Optional constants: None means "not applicable" (an ideal sensor).
_OPTIONAL = ("mdot_sensor_bandwidth",)


@dataclass(frozen=True)
class KnownConstants:
    """Constants the multi-step scheme takes as known ([S2] §5).

    Parameters
    ----------
    A_I : float
        Piston area of chamber I [m²].
    A_II : float
        Annulus area of chamber II [m²], <= A_I.
    V_0I : float
        Volume of chamber I at x_k = 0 [m³].
    V_0II : float
        Volume of chamber II at x_k = 0 [m³].
    m_k : float
        Moving mass [kg].
    p_S : float
        Supply pressure [Pa] (absolute).
    p_R : float
        Exhaust pressure [Pa] (absolute), < p_S.
    p_amb : float
        Ambient pressure on the rod cross-section [Pa] (absolute).
    T_S : float
        Supply temperature [K].
    g : float
        Gravitational acceleration along −x_k [m/s²] (0: horizontal).
    stroke : float
        Full stroke [m] (end stops at ±stroke/2); only the simulation of
        step S6 needs it.  Default 0.2 (models-spec §2).
    u_max : float
        Valve amplifier saturation [V] for S6.  Default 10.
    eps_v : float
        Stick band of the friction law [m/s].  Default 1e-4.
    mdot_sensor_bandwidth : float or None
        Corner of the mass-flow sensors' first-order lag [Hz] (the
        hot-wire of [S2]: 1 kHz), or None for a sensor without dynamics.
        The flow equations (3.x) are static in x_v and p: a lagging ṁ
        biases S0/S3 (p_krit by +0.23 on the virtual rig) unless their
        regressors pass the same lag; S2 filters its other terms
        likewise.  Default None.

    Examples
    --------
    >>> from servoid.plants.pneumatic import PNEUMATIC_NOMINAL
    >>> k = KnownConstants.from_parameters(PNEUMATIC_NOMINAL)
    >>> round(k.A_I * 1e3, 3), k.to_parameters().bore
    (1.963, 0.05)
    """

    A_I: float
    A_II: float
    V_0I: float
    V_0II: float
    m_k: float
    p_S: float
    p_R: float
    p_amb: float
    T_S: float
    g: float
    stroke: float = 0.2
    u_max: float = 10.0
    eps_v: float = 1e-4
    mdot_sensor_bandwidth: float | None = None

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if value is None and f.name in _OPTIONAL:
                continue
            if isinstance(value, bool) or not isinstance(value, (int, float, np.integer,
                                                                 np.floating)):
                raise type_error(f"KnownConstants.{f.name}", value,
                                 f"a real number [{_KNOWN_UNITS[f.name]}]")
            value = float(value)
            if not math.isfinite(value):
                raise DataError(f"KnownConstants.{f.name} must be finite, got {value}")
            if f.name != "g" and value <= 0.0:
                raise DataError(f"KnownConstants.{f.name} must be > 0 "
                                f"[{_KNOWN_UNITS[f.name]}], got {value:g}")
            object.__setattr__(self, f.name, value)
        if self.A_II > self.A_I:
            raise DataError(f"KnownConstants.A_II must be <= A_I = {self.A_I:g} m², "
                            f"got {self.A_II:g} m²")
        if self.p_R >= self.p_S:
            raise DataError(f"KnownConstants.p_R must be < p_S = {self.p_S:g} Pa, "
                            f"got {self.p_R:g} Pa")

    @classmethod
    def from_mapping(cls, table: Mapping[str, Any]) -> KnownConstants:
        """Build the constants from a table (TOML ``known`` or ``[loop]``).

        Parameters
        ----------
        table : mapping
            Keys are the field names; other keys (e.g. controller gains
            ``K_p``, ``K_d``) are ignored.

        Returns
        -------
        KnownConstants
            The validated constants.

        Raises
        ------
        DataError
            A required constant is missing.
        """
        table = as_mapping("table", table)
        names = [f.name for f in dataclasses.fields(cls)]
        required = [f.name for f in dataclasses.fields(cls)
                    if f.default is dataclasses.MISSING]
        missing = [n for n in required if n not in table]
        if missing:
            raise DataError(
                f"the known constants lack {', '.join(missing)}; give all of "
                f"{', '.join(required)} (SI units) as [identify] known = {{...}} or in [loop]"
            )
        return cls(**{n: table[n] for n in names if n in table})

    @classmethod
    def from_parameters(cls, params: PneumaticParameters) -> KnownConstants:
        """Take the known constants from a physical parameter set.

        Parameters
        ----------
        params : PneumaticParameters
            E.g. :data:`~servoid.plants.pneumatic.PNEUMATIC_NOMINAL`.

        Returns
        -------
        KnownConstants
            Its geometry, mass, supply and gravity.
        """
        as_instance("params", params, PneumaticParameters,
                    "a PneumaticParameters (e.g. servoid.plants.pneumatic.PNEUMATIC_NOMINAL)")
        return cls(A_I=params.A_I, A_II=params.A_II, V_0I=params.V_0I, V_0II=params.V_0II,
                   m_k=params.m_k, p_S=params.p_S, p_R=params.p_R, p_amb=params.p_amb,
                   T_S=params.T_S, g=params.g, stroke=params.stroke, u_max=params.u_max,
                   eps_v=params.eps_v)

    def to_parameters(self, **identified: float) -> PneumaticParameters:
        """Assemble a parameter set from these constants and estimates.

        Parameters
        ----------
        **identified : float
            Identified parameters by :class:`PneumaticParameters` field
            name (k_v, xi_v, omega_v, ad_1..ad_4, R, kappa, F_haft,
            v_krit, c_k, d_k, p_krit); the others keep the nominal value.

        Returns
        -------
        PneumaticParameters
            Bore, rod and dead volumes derived from A_I, A_II, V_0I, V_0II.

        Raises
        ------
        ModelError
            The volumes leave no positive dead volume at the stroke ends.
        """
        bore = math.sqrt(4.0 * self.A_I / math.pi)
        rod = math.sqrt(max(4.0 * (self.A_I - self.A_II) / math.pi, 0.0))
        dead_1 = self.V_0I - self.A_I * self.stroke / 2.0
        dead_2 = self.V_0II - self.A_II * self.stroke / 2.0
        for name, dead in (("V_0I", dead_1), ("V_0II", dead_2)):
            if dead <= 0.0:
                raise ModelError(
                    f"{name} leaves a dead volume of {dead:g} m³ at the end of a "
                    f"{self.stroke:g} m stroke; check {name} or the stroke"
                )
        return PneumaticParameters(
            **{k: float(v) for k, v in identified.items()}, p_S=self.p_S, p_R=self.p_R,
            p_amb=self.p_amb, T_S=self.T_S, bore=bore, rod=rod, V_dead_I=dead_1,
            V_dead_II=dead_2, stroke=self.stroke, m_k=self.m_k, g=self.g, u_max=self.u_max,
            eps_v=self.eps_v,
        )

    def to_dict(self) -> dict[str, float]:
        """Plain data for JSON or TOML (an optional constant left None is left out)."""
        return {k: v for k, v in dataclasses.asdict(self).items() if v is not None}


@dataclass(frozen=True, eq=False)
class StepResult:
    """Outcome of one step of the multi-step scheme.

    Attributes
    ----------
    step : str
        Step label, e.g. ``"S1"`` or ``"S0 p_krit"``.
    title : str
        What the step identifies.
    equation : str
        The equation solved and how, in words.
    record : str
        Name of the record (test) the step used.
    estimate : Estimate
        Physical parameters with covariance (std, 95 % intervals).
    mask : ndarray of bool, shape (N,)
        Samples of the record that entered the regression.
    method : str
        Estimator used ("svf+ls", "svf+iv", "separable_ls", "rls+ls", "ls", "iv", ...).
    notes : tuple of str
        Warnings and remarks worth a reader's attention.
    extra : mapping
        Step-specific data (raw regression parameters, RLS history,
        profile of a search, ...).
    """

    step: str
    title: str
    equation: str
    record: str
    estimate: Estimate
    mask: NDArray[np.bool_]
    method: str
    notes: tuple[str, ...] = ()
    extra: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        mask = np.array(self.mask, dtype=bool)
        mask.setflags(write=False)
        object.__setattr__(self, "mask", mask)
        object.__setattr__(self, "notes", tuple(self.notes))
        object.__setattr__(self, "extra", dict(self.extra))

    def __getitem__(self, name: str) -> float:
        return self.estimate[name]

    def std(self, name: str) -> float:
        """Standard deviation of one estimated parameter.

        Parameters
        ----------
        name : str
            Parameter name.

        Returns
        -------
        float
            Its standard deviation.
        """
        k = _index(self.estimate, name)
        return float(self.estimate.std[k])

    @property
    def values(self) -> dict[str, float]:
        """Estimated parameters by name."""
        return {n: float(v) for n, v in zip(self.estimate.names, self.estimate.parameters,
                                             strict=True)}

    @property
    def n_used(self) -> int:
        """Number of samples used."""
        return int(self.mask.sum())

    @property
    def segment(self) -> tuple[int, int]:
        """First and last sample index used (−1, −1 when none)."""
        idx = np.flatnonzero(self.mask)
        return (int(idx[0]), int(idx[-1])) if idx.size else (-1, -1)

    def to_dict(self) -> dict[str, Any]:
        """Plain data for JSON (the mask as counts and a segment)."""
        extra = {k: v for k, v in self.extra.items() if _is_small(v)}
        return {
            "step": self.step,
            "title": self.title,
            "equation": self.equation,
            "record": self.record,
            "method": self.method,
            "samples_used": self.n_used,
            "samples_total": int(self.mask.size),
            "segment": list(self.segment),
            "estimate": self.estimate.to_dict(),
            "notes": list(self.notes),
            "extra": extra,
        }

    def __str__(self) -> str:
        first, last = self.segment
        lines = [(f"{self.step}: {self.title} — {self.n_used} of {self.mask.size} samples of "
                 f"{self.record!r} (samples {first}..{last}), {self.method}")]
        for row in self.estimate.table():
            lines.append(f"  {row.name:<8} {row.value: .6g} ± {row.std:.2g} {row.unit}".rstrip())
        lines += [f"  note: {n}" for n in self.notes]
        return "\n".join(lines)


# -- helpers shared by the steps --------------------------------------------------------------


def check_record(record: object, step: str) -> Experiment:
    """Check a record argument, naming the step that needs it."""
    if not isinstance(record, Experiment):
        raise type_error(f"{step}: the record", record,
                         "an Experiment (servoid.Experiment.from_arrays or data.read_csv)")
    return record


def check_params(params: object) -> PneumaticParameters:
    """Check a physical parameter set argument."""
    return as_instance("params", params, PneumaticParameters,
                       "a PneumaticParameters (e.g. servoid.plants.pneumatic.PNEUMATIC_NOMINAL or "
                       "MultistepResult.parameters)")


def channel(record: Experiment, name: str, step: str) -> NDArray[np.float64]:
    """Return a channel, naming the step that needs it when absent."""
    check_record(record, step)
    try:
        return np.asarray(record[name], dtype=float)
    except ChannelError:
        raise ChannelError(
            f"{step} needs the channel {name!r}; the record {record.name!r} has "
            f"{', '.join(record.names)}"
        ) from None


def pressures(record: Experiment, step: str) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Return p_I, p_II, refusing non-positive absolute pressures."""
    out = []
    for name in ("p_I", "p_II"):
        p = channel(record, name, step)
        bad = np.flatnonzero(p <= 0.0)
        if bad.size:
            raise DataError(
                f"{step}: {name} must be an absolute pressure > 0 Pa, got {p[bad[0]]:g} Pa at "
                f"sample {bad[0]} ({bad.size} sample(s) <= 0); gauge pressures need p_amb "
                "added in the calibration"
            )
        out.append(p)
    return out[0], out[1]


def temperature(record: Experiment, name: str, known: KnownConstants) -> NDArray[np.float64]:
    """Return a chamber temperature channel, or T_S when not recorded."""
    if name in record.names:
        return np.asarray(record[name], dtype=float)
    return np.full(record.n_samples, known.T_S)


def mdot_sensor_lag(x: NDArray[np.float64], dt: float, known: KnownConstants,
                    step: str) -> tuple[NDArray[np.float64], int]:
    """Pass a signal through the mass-flow sensors' first-order lag.

    "Filter both sides identically": a term that is compared with a
    measured ṁ gets the sensor's known dynamics ``1/(1 + s/ω_m)``,
    discretised exactly (cubic hold) and started at steady state on
    x[0].  Returns the filtered signal and the number of start-up samples
    to discard (0 without a sensor lag, the signal returned as is).
    """
    bandwidth = known.mdot_sensor_bandwidth
    if bandwidth is None:
        return x, 0
    omega = 2.0 * math.pi * bandwidth
    if omega >= math.pi / dt:
        raise DataError(
            f"{step}: the mass-flow sensor bandwidth {bandwidth:g} Hz must lie below the "
            f"Nyquist frequency {0.5 / dt:g} Hz of the record; sample faster or leave "
            "mdot_sensor_bandwidth out (an ideal sensor)")
    out = state_variable_filter(x, dt, omega, 1, initial="steady")
    return np.array(out.derivative(0)), out.first_valid


def check_derivatives(derivatives: str) -> None:
    """Check the derivatives option."""
    check_option("derivatives", derivatives, DERIVATIVES)


def check_known(known: object) -> KnownConstants:
    """Check the known-constants argument."""
    return as_instance("known", known, KnownConstants,
                       "KnownConstants (e.g. KnownConstants.from_mapping({...}))")


def physical_estimate(
    values: Sequence[float],
    jacobian: NDArray[np.float64],
    raw: Estimate,
    names: Sequence[str],
    units: Sequence[str],
    method: str,
    options: Mapping[str, Any] | None = None,
) -> Estimate:
    """Map a raw regression estimate to physical parameters (delta method).

    ``jacobian[i, j] = ∂(physical i)/∂(raw j)``; the covariance is
    J·cov·Jᵀ.
    """
    cov = jacobian @ raw.covariance @ jacobian.T
    return Estimate(
        model=raw,
        parameters=np.asarray(values, dtype=float),
        names=tuple(names),
        covariance=0.5 * (cov + cov.T),
        noise_variance=raw.noise_variance,
        n_samples=raw.n_samples,
        method=method,
        status=raw.status,
        options=dict(options or {}),
        units=tuple(units),
    )


def ls_estimate(
    result: Any, names: Sequence[str], units: Sequence[str], method: str,
    options: Mapping[str, Any] | None = None,
) -> Estimate:
    """Wrap a :class:`~servoid.estimate.LeastSquaresResult` as an Estimate."""
    return Estimate(
        model=result,
        parameters=result.theta,
        names=tuple(names),
        covariance=result.covariance,
        noise_variance=float(result.noise_variance) if result.dof > 0 else 0.0,
        n_samples=int(result.n_rows),
        method=method,
        options={"condition": float(result.condition), **dict(options or {})},
        units=tuple(units),
    )


def window_all(mask: NDArray[np.bool_], length: int) -> NDArray[np.bool_]:
    """True where ``mask`` held for the last ``length`` samples."""
    if length <= 1:
        return mask.copy()
    bad = (~mask).astype(np.int64)
    c = np.concatenate([[0], np.cumsum(bad)])
    idx = np.arange(mask.size)
    lo = np.maximum(idx - length + 1, 0)
    return (c[idx + 1] - c[lo]) == 0


def check_positive(name: str, value: object, unit: str) -> float:
    """Check a positive finite number."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise type_error(name, value, "a real number")
    v = float(value)
    if not (math.isfinite(v) and v > 0.0):
        raise DataError(f"{name} must be > 0{' ' + unit if unit else ''}, got {v:g}")
    return v


def _index(estimate: Estimate, name: str) -> int:
    try:
        return estimate.names.index(name)
    except ValueError:
        raise ChannelError(f"no parameter {name!r}; parameters are "
                           f"{', '.join(estimate.names)}") from None


def _is_small(value: object) -> bool:
    if isinstance(value, np.ndarray):
        return value.size <= 200
    if isinstance(value, (list, tuple)):
        return len(value) <= 200
    return isinstance(value, (int, float, str, bool, dict)) or value is None


def unknown_keys(where: str, given: Mapping[str, Any], valid: Sequence[str]) -> None:
    """Raise OptionError for keys outside ``valid``."""
    unknown = sorted(set(given) - set(valid))
    if unknown:
        raise OptionError(f"unknown key(s) in {where}: {', '.join(unknown)}; valid keys are "
                          f"{', '.join(valid)}")


def newey_west_lags(n: int) -> int:
    """Bartlett-kernel bandwidth of Newey & West (1994): ⌊4 (n/100)^(2/9)⌋."""
    return int(4.0 * (max(n, 1) / 100.0) ** (2.0 / 9.0))


def hac_covariance(
    groups: Sequence[tuple[NDArray[np.float64], ...]],
    lags: int,
) -> NDArray[np.float64]:
    """LS covariance robust to coloured residuals (Newey–West, Bartlett kernel).

    The steps regress rig signals whose noise passed the anti-alias filter
    (and, in S2, the equation's SVF): their residuals are correlated over
    several samples, so σ²(ΦᵀΦ)⁻¹ understates the spread.  With H = ΣΦᵀΦ
    and g_t = φ_t e_t this returns ``H⁻¹ S H⁻¹ · n/(n − p)`` where
    ``S = Σ_l w_l Σ_t g_t g_{t−l}ᵀ``, ``w_l = 1 − |l|/(L + 1)``.

    Parameters
    ----------
    groups : sequence of (phi, resid, index) or (phi, resid, index, z)
        Regression rows of one record each (e.g. a chamber), with the
        sample index of each row: lags are taken in time, so rows across a
        gap in the mask are not paired.  With instruments ``z`` (same shape
        as ``phi``) the covariance is that of the IV estimate
        ``(ZᵀΦ)⁻¹ZᵀY``: ``H = ΣZᵀΦ``, ``g_t = z_t e_t``, ``H⁻¹ S H⁻ᵀ``.
    lags : int
        Bandwidth L [samples].

    Returns
    -------
    ndarray, shape (p, p)
        The covariance of the LS estimate.
    """
    p = groups[0][0].shape[1]
    h = np.zeros((p, p))
    s = np.zeros((p, p))
    n = 0
    for phi, resid, index, *inst in groups:
        z = inst[0] if inst else phi
        h += z.T @ phi
        n += resid.size
        if index.size == 0:
            continue
        g = np.zeros((int(index[-1]) - int(index[0]) + 1, p))
        g[index - index[0]] = z * resid[:, None]
        s += g.T @ g
        for lag in range(1, min(lags, g.shape[0] - 1) + 1):
            gam = g[lag:].T @ g[:-lag]
            s += (1.0 - lag / (lags + 1.0)) * (gam + gam.T)
    h_inv = np.linalg.inv(h)
    cov = h_inv @ s @ h_inv.T * (n / max(n - p, 1))
    return np.asarray(0.5 * (cov + cov.T))


def spectral_covariance(
    groups: Sequence[tuple[NDArray[np.float64], ...]],
    half_width: int = 4,
) -> NDArray[np.float64]:
    """LS/IV covariance with the residuals' spectra at the regressors' frequencies.

    An SVF regression's residual is the sensor noise through the equation's
    filter (in S1 ``F(s)·A(s)``, s² at mid frequencies; in S2 ``sF``):
    nearly all its power lies far above the band the regressors occupy,
    where its density is orders of magnitude lower.  σ̂²ΦᵀΦ weighs the
    regressors with the residual's total power, and a Newey–West estimate
    of a few hundred lags leaks the high band into the low one (S1's σ came
    out 2.3× its seed-to-seed spread, R's in S2 1.6×).  With the DFTs
    ``Z_{c,j}`` of the instruments and ``E_{c,j}`` of the residuals of the
    records c that share one sample clock (S2's two chambers: their
    residuals share the x_k and v_k noise) this returns ``A⁻¹ S A⁻ᵀ ·
    n/(n − p)``, ``A = Σ_c Z_cᵀΦ_c`` and ``S = (1/N) Σ_j Σ_{c,d} Re(Z_{c,j}^*
    Φ̂_{cd}(ω_j) Z_{d,j}ᵀ)``, Φ̂ the (cross-)periodogram smoothed over
    ``2·half_width + 1`` bins (Daniell).  White residuals give back
    σ̂² A⁻¹ZᵀZA⁻ᵀ.  Samples outside a record's rows count as zero.

    Parameters
    ----------
    groups : sequence of (phi, resid, index) or (phi, resid, index, z)
        Regression rows of each record with the sample index of each row
        on the common clock; with instruments ``z`` (same shape as
        ``phi``) the covariance of the IV estimate ``(ZᵀΦ)⁻¹ZᵀY``.
    half_width : int
        Half-width of the periodogram smoothing [bins of 1/(N·dt)].  The
        residual's density rises as ω² (S2) to ω⁴ (S1) from the lowest
        bins: a few bins keep that slope out of the regressors' band.

    Returns
    -------
    ndarray, shape (p, p)
        The covariance of the estimate.
    """
    start = min(int(g[2][0]) for g in groups if g[2].size)
    span = max(int(g[2][-1]) for g in groups if g[2].size) - start + 1
    p = groups[0][0].shape[1]
    a = np.zeros((p, p))
    zf, ef = [], []
    n = 0
    for phi, resid, index, *inst in groups:
        z = inst[0] if inst else phi
        a += z.T @ phi
        n += resid.size
        z_full, e_full = np.zeros((span, p)), np.zeros(span)
        z_full[index - start] = z
        e_full[index - start] = resid
        zf.append(np.fft.rfft(z_full, axis=0))
        ef.append(np.fft.rfft(e_full))
    m = max(int(half_width), 0)
    weight = np.full(ef[0].size, 2.0)  # rfft: interior bins stand for ±ω
    weight[0] = 1.0
    if span % 2 == 0:
        weight[-1] = 1.0
    s = np.zeros((p, p))
    for c, (z_c, e_c) in enumerate(zip(zf, ef, strict=True)):
        for d, (z_d, e_d) in enumerate(zip(zf, ef, strict=True)):
            if d < c:
                continue
            cross = _daniell(e_c * e_d.conj(), m) / span
            term = ((z_c.conj().T * (weight * cross)) @ z_d).real / span
            s += term if c == d else term + term.T
    a_inv = np.linalg.inv(a)
    cov = a_inv @ s @ a_inv.T * (n / max(n - p, 1))
    return np.asarray(0.5 * (cov + cov.T))


def _daniell(x: NDArray[np.complex128], m: int) -> NDArray[np.complex128]:
    """Moving average over 2m + 1 bins, mirrored at 0 and Nyquist."""
    if m == 0 or x.size <= m + 1:
        return x
    ext = np.concatenate([x[m:0:-1].conj(), x, x[-2:-m - 2:-1].conj()])
    kernel = np.full(2 * m + 1, 1.0 / (2 * m + 1))
    return np.convolve(ext.real, kernel, "valid") + 1j * np.convolve(ext.imag, kernel, "valid")


def propagate(
    cov: NDArray[np.float64],
    solve: Any,
    inserted: Sequence[tuple[float, float]],
) -> tuple[NDArray[np.float64], list[NDArray[np.float64]]]:
    """Add the uncertainty of inserted estimates to a step's covariance.

    Delta method, the inserted values taken as independent of this step's
    data: ``cov + Σ_j g_j g_jᵀ σ_j²`` with ``g_j = ∂θ/∂z_j`` by central
    differences ``(θ(z_j + h_j) − θ(z_j − h_j)) / 2h_j``.

    Parameters
    ----------
    cov : ndarray, shape (p, p)
        The step's own covariance.
    solve : callable
        ``solve(j, delta)`` → θ re-estimated with inserted value j moved by
        ``delta``.
    inserted : sequence of (value, step)
        Per inserted value its std σ_j and the difference step h_j (> 0);
        entries with σ_j = 0 are skipped.

    Returns
    -------
    (ndarray, list of ndarray)
        The covariance and the gradients g_j (zeros where skipped).
    """
    out = np.array(cov, dtype=float)
    grads = []
    for j, (std, h) in enumerate(inserted):
        if std <= 0.0:
            grads.append(np.zeros(out.shape[0]))
            continue
        g = (np.asarray(solve(j, +h), dtype=float) - np.asarray(solve(j, -h), dtype=float)) / (
            2.0 * h)
        out += np.outer(g, g) * std**2
        grads.append(g)
    return out, grads
