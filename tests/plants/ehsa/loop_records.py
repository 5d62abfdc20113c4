"""Shared truth for the closed-loop tests: spec §4, Set B reduced at 1 kHz."""

from __future__ import annotations

import numpy as np

from servoid.data import Experiment
from servoid.plants.ehsa import FeedbackLoop
from servoid.signals import prbs

TRUTH = np.array([3451.7, 163.3, 0.249])  # K [1/s], omega_hp [rad/s], delta_hp [-]
DT = 1e-3
LOOP = FeedbackLoop(c=0.01, F=0.01)


def reference() -> np.ndarray:
    """PRBS n = 11, 10 samples/bit, ±1 mm: 20 470 samples."""
    return prbs(11, clock=10, amplitude=1e-3, periods=1, dt=DT).values


def record(y: np.ndarray, r: np.ndarray) -> Experiment:
    return Experiment.from_arrays(DT, r=r, y=y, units={"r": "m", "y": "m"})


def halves(exp: Experiment) -> tuple[Experiment, Experiment]:
    n = exp.n_samples // 2
    return exp.slice(0, n), exp.slice(n, None)


def output_noise(y0: np.ndarray, snr_db: float, seed: int) -> np.ndarray:
    """White output noise at SNR = 20·log10(std y / σ) [dB]."""
    rng = np.random.default_rng(seed)
    return y0 + rng.normal(0.0, y0.std() / 10 ** (snr_db / 20), y0.size)
