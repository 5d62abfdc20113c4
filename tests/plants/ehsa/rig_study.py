"""Coverage of the one-step intervals on rig data servoid did not make with its own model.

The generator is the virtual EHSA bench (:mod:`servoid.bench`): the
continuous reduced loop integrated exactly at 20× the sample rate
(``oversample = 4`` at ``f_acq = 5·f_s``), white sensor noise added before
the 4th-order Butterworth anti-alias filter at 0.2·f_acq, 16-bit ADC and
DAC, and the experiment TOML written by :func:`write_bench_files`, which
servoid loads (FIR decimation by 5, mean removed, first half for
estimation) and identifies with its workflow, as a user would.  Runs cycle
through four rigs:

- Set B (ω_hp = 163 rad/s) at f_s = 1 kHz and Set C (ω_hp = 8944 rad/s) at
  f_s = 10 kHz (a rate that resolves it),
- the reference read back through the filter (band-limited) or logged as
  the DAC command (a staircase, the filter and decimation on y only),

with the SNR of the position drawn uniformly from 25–45 dB and the seed of
the noise per run.  A run scores a hit per parameter whose 95 % interval
holds the truth.
"""

from __future__ import annotations

import dataclasses
import tempfile
import warnings
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType

import numpy as np

from servoid.data import load_experiment_spec
from servoid.plants.ehsa import SET_B, SET_C, EhsaBench, run, write_bench_files
from servoid.signals import prbs
from servoid.workflows import identify

#: (parameter set, f_s [Hz], reference) of the rigs, in the order runs cycle through them.
RIGS = (("B", 1000.0, "readback"), ("B", 1000.0, "command"),
        ("C", 10000.0, "readback"), ("C", 10000.0, "command"))
NAMES = ("K", "omega_hp", "delta_hp")


@dataclass(frozen=True)
class RunResult:
    """One rig run: which rig, its SNR, the z-scores and what the fit said."""

    rig: tuple[str, float, str]
    snr_db: float
    z: np.ndarray  # (estimate − truth)/std for K, omega_hp, delta_hp
    covered: np.ndarray  # truth inside the 95 % interval, per parameter
    flags: tuple[str, ...]
    intersample: str


def rig_run(k: int, seed0: int, register: int, folder: Path) -> RunResult:
    """Run rig ``k % 4`` with seed ``seed0 + k`` and identify it from its files."""
    name, fs, reference = RIGS[k % len(RIGS)]
    seed = seed0 + k
    snr = float(np.random.default_rng(seed).uniform(25.0, 45.0))
    bench = EhsaBench(params=SET_B if name == "B" else SET_C, f_s=fs, f_acq=5.0 * fs,
                      snr_db=snr, reference=reference)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the rig's notes (none expected) are in rec.warnings
        rec = run(bench, prbs(register, clock=10, amplitude=1e-3, dt=bench.dt), rng=seed)
        files = write_bench_files(rec, folder / str(k), overwrite=True)
        spec = load_experiment_spec(files[1])
        spec = dataclasses.replace(
            spec, identify=MappingProxyType({**spec.identify, "approach": "one-step"}))
        result = identify(spec, write=False).results["one-step"]
    est = result.estimate
    truth = np.array([rec.truth.K, rec.truth.omega_hp, rec.truth.delta_hp])
    lo, hi = est.confidence_intervals(0.95).T
    return RunResult((name, fs, reference), snr, (est.parameters - truth) / est.std,
                     (lo <= truth) & (truth <= hi), result.flags, result.intersample)


def study(runs: int, seed0: int, register: int) -> list[RunResult]:
    """Run `runs` rigs (cycling through :data:`RIGS`) in a temporary folder."""
    with tempfile.TemporaryDirectory() as tmp:
        return [rig_run(k, seed0, register, Path(tmp)) for k in range(runs)]


def summary(results: Iterable[RunResult]) -> dict[str, object]:
    """Coverage per parameter and pooled, mean z², per rig, as plain data."""
    results = list(results)
    covered = np.array([r.covered for r in results])
    z = np.array([r.z for r in results])
    per_rig = {}
    for rig in RIGS:
        sel = [i for i, r in enumerate(results) if r.rig == rig]
        if sel:
            per_rig["/".join(map(str, rig))] = {
                "runs": len(sel),
                "coverage": dict(zip(NAMES, covered[sel].mean(axis=0).tolist(), strict=True)),
                "mean_z2": dict(zip(NAMES, (z[sel] ** 2).mean(axis=0).tolist(), strict=True)),
            }
    return {
        "runs": len(results),
        "coverage": dict(zip(NAMES, covered.mean(axis=0).tolist(), strict=True)),
        "pooled": float(covered.mean()),
        "mean_z2": dict(zip(NAMES, (z**2).mean(axis=0).tolist(), strict=True)),
        "flagged": sum(bool(r.flags) for r in results),
        "rigs": per_rig,
    }
