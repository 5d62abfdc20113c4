"""Closed loops that servoid's estimators do not share: an independent generator.

Each rig is a continuous plant with an analog anti-alias filter in its
measurement path, simulated far above the sample rate (``oversample`` fast
steps per sample, each the exact matrix-exponential step of the analog
state with the DAC's output held), sampled at ``dt``, with coloured noise
on the measurement.  A digital controller (given in continuous form and
discretised by Tustin, or directly in discrete form) reads the noisy
measurement at each sample and writes the DAC, optionally through a
transport delay of whole samples.  Only numpy and scipy are used: nothing
here calls servoid.

The truth every method is held to is the sampled plant from the logged u
to the noise-free logged y: the zero-order-hold discretisation of
``plant × anti-alias`` with the transport delay, computed by scipy
(:func:`scipy.signal.cont2discrete`).

Rigs
----
``motor``
    DC motor (R = 1 Ω, L = 1 mH, k = 0.05 N·m/A, J = 1e-4 kg·m²,
    b = 1e-4 N·m·s) with a 5:1 gear and a 5 mm ball screw driving 10 kg:
    voltage → load velocity [mm/s], under a PI speed controller
    (continuous kp = 1 V·s/mm, Ti = 20 ms, Tustin at 1 kHz), 1st-order
    anti-alias filter at 100 Hz, ARMA(1, 1) noise, PRBS reference of
    ±10 mm/s with a 50 ms bit.  Third order.
``unstable``
    10/((s − 3)(s + 20)) under a PD controller with a filtered derivative
    (continuous kp = 12, kd = 0.5, τ = 20 ms, Tustin at 100 Hz),
    anti-alias filter at 20 Hz.  Third order, one pole outside the unit
    circle.
``delay``
    2/(0.5 s + 1) behind a transport delay of three samples under a
    discrete PI at 20 Hz (backward Euler), anti-alias filter at 2 Hz.
    Second order, nk = 4.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy import linalg, signal

__all__ = ["RIGS", "Record", "Rig", "prbs_reference"]


def _tustin(num: list[float], den: list[float], dt: float) -> tuple[np.ndarray, np.ndarray]:
    b, a, _ = signal.cont2discrete((num, den), dt, method="bilinear")
    b = np.atleast_1d(np.squeeze(b))
    return b / a[0], a / a[0]


@dataclass(frozen=True)
class Rig:
    """A continuous plant under a digital controller, as a rig records it."""

    name: str
    plant: tuple[list[float], list[float]]  # continuous num, den in s
    aa_hz: float  # 1st-order analog anti-alias filter in the measurement path [Hz]
    dt: float
    controller: tuple[np.ndarray, np.ndarray]  # discrete num, den in z (descending powers)
    delay: int = 0  # transport delay of the DAC output [samples]
    noise: tuple[list[float], list[float]] = ([1.0], [1.0])  # C, D monic in q⁻¹
    noise_std: float = 0.1
    clock: int = 5  # PRBS samples per bit
    amplitude: float = 1.0
    oversample: int = 20
    orders: tuple[int, int, int] = (2, 2, 1)  # nb, nf, nk of the sampled plant
    units: tuple[str, str] = ("V", "")
    saturation: float | None = None  # DAC limit ±[u unit]
    _cache: dict = field(default_factory=dict, compare=False, repr=False)

    # -- the truth --------------------------------------------------------------------------
    def analog(self) -> tuple[np.ndarray, np.ndarray]:
        """num, den of plant × anti-alias in s."""
        wc = 2 * np.pi * self.aa_hz
        num = np.polymul(self.plant[0], [wc])
        den = np.polymul(self.plant[1], [1.0, wc])
        return np.atleast_1d(num), np.atleast_1d(den)

    def sampled(self) -> tuple[np.ndarray, np.ndarray]:
        """b (from q^-nk), f (monic) of the sampled plant u → y."""
        num, den = self.analog()
        bz, az, _ = signal.cont2discrete((num, den), self.dt, method="zoh")
        bz = np.atleast_1d(np.squeeze(bz)) / az[0]
        az = az / az[0]
        nb, nf, nk = self.orders
        lead = np.flatnonzero(np.abs(bz) > 1e-12 * np.max(np.abs(bz)))[0]
        b = bz[lead:]
        assert lead + self.delay == nk and b.size == nb and az.size == nf + 1, (lead, b, az)
        return b, az

    def theta(self) -> np.ndarray:
        """(b0…, f1…): the OE / BJ / two-stage / indirect plant parameters."""
        b, f = self.sampled()
        return np.concatenate([b, f[1:]])

    def theta_arx(self) -> np.ndarray:
        """(a1…, b0…): the CLIV parameters."""
        b, f = self.sampled()
        return np.concatenate([f[1:], b])

    # -- the simulation ---------------------------------------------------------------------
    def _maps(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        if "maps" not in self._cache:
            num, den = self.analog()
            a, b, c, _ = signal.tf2ss(num, den)
            n = a.shape[0]
            h = self.dt / self.oversample
            big = np.zeros((n + 1, n + 1))
            big[:n, :n], big[:n, n] = a * h, b[:, 0] * h
            e = linalg.expm(big)
            phi, gam = e[:n, :n], e[:n, n]
            # one sample = `oversample` fast steps with the input held
            a_s, b_s = np.eye(n), np.zeros(n)
            for _ in range(self.oversample):
                a_s, b_s = phi @ a_s, phi @ b_s + gam
            self._cache["maps"] = (a_s, b_s, c[0])
        return self._cache["maps"]

    def run(self, r: np.ndarray, seed: int, *, closed: bool = True,
            u_open: np.ndarray | None = None) -> Record:
        """Simulate the loop driven by r (or the plant open loop by `u_open`)."""
        a_s, b_s, c = self._maps()
        rng = np.random.default_rng(seed)
        n = r.size if closed else u_open.size
        e = rng.standard_normal(n) * self.noise_std
        v = signal.lfilter(self.noise[0], self.noise[1], e)
        cn, cd = self.controller
        cn = np.concatenate([np.zeros(cd.size - cn.size), cn]) / cd[0]
        cd = cd / cd[0]
        x = np.zeros(a_s.shape[0])
        u = np.zeros(n)
        y = np.zeros(n)
        ein = np.zeros(cd.size)  # controller input history e(k), e(k−1), …
        uout = np.zeros(cd.size)  # controller output history
        fifo = np.zeros(self.delay + 1)
        for k in range(n):
            y[k] = c @ x + v[k]
            if closed:
                ein = np.roll(ein, 1)
                ein[0] = r[k] - y[k]
                uk = cn @ ein - cd[1:] @ uout[:-1]
                uout = np.roll(uout, 1)
                uout[0] = uk
            else:
                uk = u_open[k]
            if self.saturation is not None:
                uk = float(np.clip(uk, -self.saturation, self.saturation))
                if closed:
                    uout[0] = uk
            u[k] = uk
            fifo = np.roll(fifo, -1)
            fifo[-1] = uk
            x = a_s @ x + b_s * fifo[0]
        return Record(self, r if closed else None, u, y, seed)

    def closed(self, seed: int, n: int, clock: int | None = None,
               amplitude: float | None = None) -> Record:
        """A closed-loop record driven by a random binary reference."""
        r = prbs_reference(n, clock or self.clock, amplitude or self.amplitude, 10_000 + seed)
        return self.run(r, seed)

    def open(self, seed: int, n: int, clock: int | None = None) -> Record:
        """An open-loop record: the plant driven by a random binary input."""
        u = prbs_reference(n, clock or self.clock, 1.0, 20_000 + seed)
        return self.run(np.zeros(0), seed, closed=False, u_open=u)


@dataclass(frozen=True)
class Record:
    """One simulated record."""

    rig: Rig
    r: np.ndarray | None
    u: np.ndarray
    y: np.ndarray
    seed: int

    def experiment(self):  # type: ignore[no-untyped-def]
        """The record as a servoid Experiment (r, u, y)."""
        from servoid.data import Experiment

        if self.r is None:
            return Experiment.from_arrays(self.rig.dt, u=self.u, y=self.y)
        return Experiment.from_arrays(self.rig.dt, r=self.r, u=self.u, y=self.y)


def prbs_reference(n: int, clock: int, amplitude: float, seed: int) -> np.ndarray:
    """A random binary signal ±amplitude holding each level `clock` samples."""
    bits = np.sign(np.random.default_rng(seed).standard_normal(-(-n // clock)))
    return amplitude * np.repeat(bits, clock)[:n]


def _motor() -> Rig:
    R, L, k, J, b = 1.0, 1e-3, 0.05, 1e-4, 1e-4
    gear, lead, mass = 5.0, 5e-3, 10.0
    to_load = lead / (2 * np.pi * gear) * 1e3  # rad/s of the motor → mm/s of the load
    j_eq = J + mass * (lead / (2 * np.pi)) ** 2 / gear**2
    den = np.polyadd(np.polymul([L, R], [j_eq, b]), [k * k])
    kp, ti = 1.0, 0.02
    return Rig("motor", ([k * to_load], list(den)), 100.0, 1e-3,
               _tustin([kp * ti, kp], [ti, 0.0], 1e-3), noise=([1.0, 0.5], [1.0, -0.9]),
               noise_std=0.3, clock=50, amplitude=10.0, orders=(3, 3, 1), units=("V", "mm/s"))


def _unstable() -> Rig:
    kp, kd, tau = 12.0, 0.5, 0.02
    # kp + kd s/(τ s + 1) = ((kp τ + kd) s + kp)/(τ s + 1)
    return Rig("unstable", ([10.0], [1.0, 17.0, -60.0]), 20.0, 0.01,
               _tustin([kp * tau + kd, kp], [tau, 1.0], 0.01),
               noise=([1.0, 0.5], [1.0, -0.9]), noise_std=0.005, clock=3, amplitude=0.2,
               orders=(3, 3, 1))


def _delay() -> Rig:
    kp, ki, dt = 0.5, 1.0, 0.05
    return Rig("delay", ([2.0], [0.5, 1.0]), 2.0, dt,
               (np.array([kp + ki * dt, -kp]), np.array([1.0, -1.0])), delay=3,
               noise=([1.0, 0.5], [1.0, -0.9]), noise_std=0.02, clock=4, amplitude=1.0,
               orders=(2, 2, 4))


#: the rigs by name
RIGS = {rig.name: rig for rig in (_motor(), _unstable(), _delay())}
