"""An EHSA rig that servoid does not share: Merritt's flow law in scipy ``solve_ivp``.

The generator of the validity studies (issue 24).  Nothing here comes from
servoid's EHSA simulator, bench or sampled models:

* the plant is written from Merritt (*Hydraulic Control Systems*, §5–6)
  as three ODEs — piston position y, velocity v and load pressure P_L —
  fed by the valve flow ``Q = C_d·w·x_s·√((P_s − sgn(x_s)·P_L)/ρ)`` (the
  flow law, optional) or its linearisation ``K_qs·x_s``; the valve opening
  ``x_s = K_s2·u`` follows the loop's input ``u = c·r − F·y`` at once or
  through a first-order lag τ_v, and may be clipped (a driver that
  saturates);
* it is integrated by ``scipy.integrate.solve_ivp`` (DOP853, rtol 1e-10)
  over each interval where the command is constant, and read at
  ``f_hi = 50·f_s`` from the dense output (at an offset for a skewed
  channel);
* both channels pass a fourth-order Butterworth anti-alias filter (bilinear
  at f_hi, cutoff 0.2·f_acq), are sampled at ``f_acq = 5·f_s``, get white
  sensor noise (and optional quantisation), and are decimated by
  ``scipy.signal.resample_poly`` (a Kaiser FIR, not servoid's Hamming
  design);
* the truth is the loop linearised at P_L = 0, computed from the physical
  constants with Merritt's load term ``B_p·K_ce/A_p²`` kept (the spec's
  formulas drop it).

The clean trajectory is simulated once per rig (cached) and each seed adds
its own noise, so a 100-seed study costs one integration.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from functools import lru_cache

import numpy as np
from scipy import integrate, signal

#: Set B (models-spec §1.3): SI units.
SET_B = {
    "P_s": 21e6, "beta_e": 700e6, "rho": 850.0, "C_d": 0.61, "w": 3.0e-3, "A_p": 1.0e-3,
    "V_t": 7.0e-5, "K_ce": 2e-12, "B_p": 2000.0, "M_t": 1500.0, "K_s2": 12.0,
    "c": 0.01, "F": 0.01,
}


@dataclass(frozen=True)
class Rig:
    """One rig: the actuator, its loop's truths and the test.

    ``reference`` is ``"prbs"`` (n = `register`, `clock` samples per bit),
    ``"sine"`` (one sine at `sine_hz`) or ``"noise"`` (a Gaussian random-
    phase multisine from 0.2 to `band_hz`, rms `amplitude`).  ``amplitude``
    is the PRBS/sine peak or the noise rms [m].  ``c_true`` is the true
    reference gain (the identification is told ``SET_B["c"]``), ``skew`` the
    delay of the position channel against the reference [s], ``clip`` the
    valve command's limit as a multiple of the reference's rms (None: none),
    ``bits`` a quantised read-back of the reference (None: 16 bits with
    dither, i.e. none), ``flow_law`` Merritt's law or its linearisation.
    """

    amplitude: float = 0.2e-3
    flow_law: bool = True
    reference: str = "prbs"
    register: int = 10
    clock: int = 10
    sine_hz: float = 2.0
    band_hz: float = 40.0
    c_true: float = 0.01
    skew: float = 0.0
    clip: float | None = None
    bits: int | None = None
    tau_v: float = 0.0
    f_s: float = 1000.0
    params: tuple[tuple[str, float], ...] = field(default=tuple(SET_B.items()))

    @property
    def p(self) -> dict[str, float]:
        return dict(self.params)

    def truth(self) -> np.ndarray:
        """K [1/s], ω_hp [rad/s], δ_hp [-] of the loop linearised at P_L = 0."""
        p = self.p
        k_qs = p["C_d"] * p["w"] * math.sqrt(p["P_s"] / p["rho"])
        a2 = p["A_p"] ** 2 + p["B_p"] * p["K_ce"]
        k = p["K_s2"] * k_qs * p["A_p"] / a2
        w = math.sqrt(4.0 * p["beta_e"] * a2 / (p["V_t"] * p["M_t"]))
        d = w * (p["M_t"] * p["K_ce"] + p["B_p"] * p["V_t"] / (4.0 * p["beta_e"])) / (2.0 * a2)
        return np.array([k, w, d])

    def with_(self, **changes: object) -> Rig:
        return replace(self, **changes)


def command(rig: Rig) -> tuple[np.ndarray, int]:
    """The designed reference at f_s and the samples per constant piece (its hold)."""
    dt = 1.0 / rig.f_s
    if rig.reference == "prbs":
        bits = _mls(rig.register)
        return rig.amplitude * np.repeat(2.0 * bits - 1.0, rig.clock), rig.clock
    n = 2 ** rig.register * rig.clock
    t = np.arange(n) * dt
    if rig.reference == "sine":
        return rig.amplitude * np.sin(2.0 * math.pi * rig.sine_hz * t), 1
    if rig.reference == "noise":
        freqs = np.fft.rfftfreq(n, dt)
        spec = np.zeros(freqs.size, complex)
        band = (freqs >= 0.2) & (freqs <= rig.band_hz)
        spec[band] = np.exp(2j * math.pi * np.random.default_rng(7).random(band.sum()))
        x = np.fft.irfft(spec, n)
        return rig.amplitude * x / x.std(), 1
    raise ValueError(rig.reference)


def clean(rig: Rig) -> tuple[np.ndarray, np.ndarray, float]:
    """Noise-free (r, y) after the anti-alias filter at f_acq, and the rms of y at f_s."""
    r_acq, y_acq, rms, _ = _simulate(rig)
    return r_acq, y_acq, rms


@lru_cache(maxsize=16)
def peak_load_pressure(rig: Rig) -> float:
    """Largest |P_L|/P_s of the run (at the acquisition instants)."""
    return _simulate(rig)[3]


@lru_cache(maxsize=16)
def _simulate(rig: Rig) -> tuple[np.ndarray, np.ndarray, float, float]:
    p = rig.p
    ref, hold = command(rig)
    q = 5  # f_acq = 5·f_s
    f_acq = q * rig.f_s
    clip = None if rig.clip is None else rig.clip * float(np.std(ref))
    k_qs = p["C_d"] * p["w"] * math.sqrt(p["P_s"] / p["rho"])
    kb = 4.0 * p["beta_e"] / p["V_t"]
    # the analog anti-alias filter as states, one copy per channel (exact, no sampling)
    bz, ba = signal.butter(4, 2.0 * math.pi * 0.2 * f_acq, analog=True)
    fa, fb, fc, _ = signal.tf2ss(bz, ba)
    fb = fb[:, 0]
    lag = rig.tau_v > 0.0
    n_plant = 4 if lag else 3

    def rhs(t: float, x: np.ndarray, r: float) -> np.ndarray:
        y, v, pl = x[0], x[1], x[2]
        u = rig.c_true * r - p["F"] * y
        xs = x[3] if lag else p["K_s2"] * u
        if clip is not None:
            lim = p["K_s2"] * rig.c_true * clip
            xs = min(max(xs, -lim), lim)
        if rig.flow_law:
            flow = p["C_d"] * p["w"] * xs * math.sqrt(
                max(p["P_s"] - math.copysign(1.0, xs) * pl, 0.0) / p["rho"])
        else:
            flow = k_qs * xs
        out = np.empty(x.size)
        out[0] = v
        out[1] = (p["A_p"] * pl - p["B_p"] * v) / p["M_t"]
        out[2] = kb * (flow - p["A_p"] * v - p["K_ce"] * pl)
        if lag:
            out[3] = (p["K_s2"] * u - x[3]) / rig.tau_v
        fy = x[n_plant:n_plant + 4]
        fr = x[n_plant + 4:]
        out[n_plant:n_plant + 4] = fa @ fy + fb * y
        out[n_plant + 4:] = fa @ fr + fb * r
        return out

    x = np.zeros(n_plant + 8)
    dt = 1.0 / rig.f_s
    n = ref.size
    y_acq = np.empty(n * q)
    r_acq = np.empty(n * q)
    peak = 0.0
    grid = np.arange(hold * q) / f_acq
    scale = np.concatenate([[1e-3, 1e-2, 1e6], [1e-4] if lag else [], np.full(8, 1e-3)])
    for k0 in range(0, n, hold):
        t0, t1 = k0 * dt, (k0 + hold) * dt
        sol = integrate.solve_ivp(rhs, (t0, t1 + rig.skew + 1e-12), x, method="DOP853",
                                  rtol=1e-10, atol=1e-12 * scale, args=(float(ref[k0]),),
                                  dense_output=True)
        piece = slice(k0 * q, (k0 + hold) * q)
        # the position channel is read late by the skew (a multiplexed ADC)
        y_acq[piece] = fc[0] @ sol.sol(t0 + grid + rig.skew)[n_plant:n_plant + 4]
        states = sol.sol(t0 + grid)
        r_acq[piece] = fc[0] @ states[n_plant + 4:]
        peak = max(peak, float(np.max(np.abs(states[2]))))
        x = sol.sol(t1)
    y_fs = signal.resample_poly(y_acq, 1, q)
    return r_acq, y_acq, float(np.std(y_fs)), peak / p["P_s"]


def record(rig: Rig, snr_db: float, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """(r, y) at f_s with white sensor noise at f_acq (SNR of y at f_s) for one seed."""
    r_acq, y_acq, rms = clean(rig)
    rng = np.random.default_rng(seed)
    # white at f_acq, then the decimation keeps 1/5 of its power
    sigma = rms / 10 ** (snr_db / 20) * math.sqrt(5.0)
    y = y_acq + rng.normal(0.0, sigma, y_acq.size)
    r = r_acq.copy()
    if rig.bits is not None:
        lsb = 2.0 * 0.023 / 2**rig.bits  # ±23 mm command range over the converter
        r = lsb * np.round(r / lsb)
    r_fs = signal.resample_poly(r, 1, 5)
    y_fs = signal.resample_poly(y, 1, 5)
    return r_fs - r_fs.mean(), y_fs - y_fs.mean()


def _mls(n: int) -> np.ndarray:
    taps = {7: (7, 6), 8: (8, 6, 5, 4), 9: (9, 5), 10: (10, 7), 11: (11, 9)}[n]
    state = [1] * n
    out = np.empty(2**n - 1)
    for i in range(out.size):
        out[i] = state[-1]
        fb = 0
        for t in taps:
            fb ^= state[t - 1]
        state = [fb, *state[:-1]]
    return out
