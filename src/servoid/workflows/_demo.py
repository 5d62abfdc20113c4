"""The demo: plan a PRBS test, rehearse it on a known servo, identify, validate.

A stand-in until the closed-loop actuator demo exists: a position servo
with a known second-order response is driven by a designed PRBS, its output
is recorded with noise into a CSV rig file with a matching experiment TOML,
and :func:`~servoid.workflows.identify` runs on those files exactly as on a
real bench record. Every printed number comes from the run.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..data import Experiment, write_csv, write_experiment_spec
from ..models import PolynomialModel, TransferFunction, c2d
from ..signals import Excitation, prbs
from ._identify import IdentificationResult, identify

__all__ = ["DemoResult", "run_demo"]

# The known system: ω_n = 2π·4 Hz, ζ = 0.35, gain 2 mm/V, sampled at 200 Hz.
_OMEGA = 2 * np.pi * 4.0
_ZETA = 0.35
_GAIN = 2e-3
_DT = 0.005


@dataclass(frozen=True, eq=False)
class DemoResult:
    """The demo's truth, design and identification."""

    truth: PolynomialModel
    excitation: Excitation
    snr_db: float
    identification: IdentificationResult

    def table(self) -> list[dict[str, Any]]:
        """Truth vs estimate per ARX coefficient."""
        truth = np.concatenate([self.truth.a[1:], self.truth.b[0]])
        rows = []
        est = self.identification.estimate
        for row, true in zip(est.table(), truth, strict=True):
            rows.append(
                {"name": row.name, "truth": float(true), "estimate": row.value, "std": row.std,
                 "ci95": [row.ci_low, row.ci_high], "inside_ci": row.ci_low <= true <= row.ci_high}
            )
        return rows

    def to_dict(self) -> dict[str, Any]:
        """Plain data for ``--json``."""
        v = self.identification.validation
        return {
            "excitation": dict(self.excitation.description),
            "snr_db": self.snr_db,
            "parameters": self.table(),
            "validation": {"fit_percent": v.fit_percent, "whiteness_pvalue": v.residuals.whiteness_pvalue,
                           "is_white": v.residuals.is_white},
            "folder": str(self.identification.folder),
            "files": [str(f) for f in self.identification.files],
        }

    def __str__(self) -> str:
        v = self.identification.validation
        ex = self.excitation
        lines = [
            "servoid demo: PRBS test of a position servo with known dynamics",
            f"  excitation: PRBS, {ex.n_samples} samples at {1 / ex.dt:g} Hz, clock {ex.clock} "
            f"samples/bit, ±{ex.amplitude:g} V, band {ex.band[0]:.3g}–{ex.band[1]:.3g} Hz",
            f"  output noise: SNR {self.snr_db:.1f} dB (equation error)",
            "",
            f"  {'param':<6} {'truth':>11} {'estimate':>11} {'std':>9}  {'95 % CI':<25} in CI",
        ]
        for r in self.table():
            lo, hi = r["ci95"]
            lines.append(
                f"  {r['name']:<6} {r['truth']:>11.6g} {r['estimate']:>11.6g} {r['std']:>9.2e}  "
                f"{f'[{lo:.6g}, {hi:.6g}]':<25} {'yes' if r['inside_ci'] else 'NO'}"
            )
        lines += [
            "",
            f"  validation (held-back half): simulation fit {v.fit_percent:.2f} %, "
            f"{v.horizon}-step prediction fit {v.prediction_fit_percent:.2f} %",
            f"  residuals {'white' if v.residuals.is_white else 'NOT white'} "
            f"(Ljung–Box p = {v.residuals.whiteness_pvalue:.3f}), "
            f"{'independent of' if v.residuals.is_independent else 'correlated with'} the input",
            f"  results: {self.identification.folder}",
        ]
        return "\n".join(lines)


def run_demo(
    out: str | os.PathLike[str] = "servoid-demo", *, seed: int = 2026, snr_db: float = 30.0
) -> DemoResult:
    """Run the demo and write its folder (rig file, TOML, results, figures).

    Parameters
    ----------
    out : path
        Folder for the demo's files; files of an earlier demo run there are replaced.
    seed : int
        Seed of the noise generator.
    snr_db : float
        Signal-to-noise ratio of the output [dB].
    """
    out = Path(out)
    rng = np.random.default_rng(seed)
    plant = TransferFunction([_GAIN * _OMEGA**2], [1.0, 2 * _ZETA * _OMEGA, _OMEGA**2])
    truth = c2d(plant, _DT, "zoh").to_polynomial("arx")
    excitation = prbs(9, clock=3, amplitude=1.0, periods=4, dt=_DT)
    u = excitation.values
    y_clean = truth.simulate(u)
    # Equation-error noise e/A keeps the truth inside the ARX structure, so the
    # reported intervals are exact in distribution.
    e_scale = np.std(y_clean) / 10 ** (snr_db / 20)
    e = rng.standard_normal(u.size)
    from scipy.signal import lfilter

    colored = lfilter([1.0], truth.a, e)
    e *= e_scale / np.std(colored)
    y = y_clean + lfilter([1.0], truth.a, e)
    exp = Experiment.from_arrays(_DT, u=u, y=y, names={"u": "valve_cmd", "y": "position"},
                                 units={"valve_cmd": "V", "position": "m"}, name="demo")
    out.mkdir(parents=True, exist_ok=True)
    write_csv(exp, out / "demo.csv", overwrite=True)
    write_experiment_spec(
        {
            "data": {"file": "demo.csv", "time": "time"},
            "channels": {"valve_cmd": {"role": "u", "unit": "V"},
                         "position": {"role": "y", "unit": "m"}},
            "preprocess": {"detrend": "mean"},
            "split": {"fraction": 0.5, "period": excitation.period},
            "identify": {"method": "arx", "input": "u", "na": 2, "nb": 2, "nk": 1},
            "report": {"folder": "results"},
        },
        out / "demo.toml",
        overwrite=True,
    )
    result = identify(out / "demo.toml", overwrite=True)
    return DemoResult(truth, excitation, snr_db, result)
