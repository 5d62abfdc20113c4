"""Frequency-domain identification of an actuator: multisine BLA, LPM, ML model, acceptance.

The actuator is a continuous second-order servo (ω_n = 2π·8 rad/s, ζ = 0.4: its resonance is
2.70 dB at 6.60 Hz) behind a mild cubic, recorded by servoid's virtual rig (20× oversampled,
ZOH input, white output noise).  The script

1. plans a random-odd multisine test (6 realisations × 2 periods after a transient period)
   and measures the best linear approximation with its noise and nonlinear variances and the
   odd/even distortion levels;
2. fits a continuous transfer function by maximum likelihood, the order chosen by the
   cost-function test, and reads the acceptance numbers with 95 % intervals;
3. does the same from a white-noise record with the local polynomial method, and shows what
   the Welch H1 of the same record reads off its lines.

It prints only (no files).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from servoid.bench import simulate_lti
from servoid.data import Experiment
from servoid.estimate import estimate_frf
from servoid.frequency import (
    acceptance_numbers,
    estimate_bla,
    estimate_lpm,
    judge,
    select_ml_order,
)
from servoid.models import TransferFunction, resonance_peak
from servoid.signals import plan_multisine, random_multisine

DT = 0.01
WN = 2 * np.pi * 8.0
PLANT = TransferFunction([WN**2], [1.0, 0.8 * WN, WN**2])


def hold(frm):
    """The lines with the ZOH's response divided out (the rig holds its input)."""
    wt2 = np.pi * frm.frequency * DT
    h = np.exp(-1j * wt2) * np.sinc(wt2 / np.pi)
    s = np.abs(h) ** 2
    nl = frm.nonlinear_variance
    return dataclasses.replace(frm, response=frm.response / h, variance=frm.variance / s,
                               noise_variance=frm.noise_variance / s,
                               nonlinear_variance=None if nl is None else nl / s)


def show(numbers):
    for n in numbers:
        if np.isfinite(n.ci_low):
            lines = f"{n.measured:.4f}" if np.isfinite(n.measured) else "-"
            print(f"  {n.label:<36} {n.value:9.4f}  95 % [{n.ci_low:.4f}, {n.ci_high:.4f}]  "
                  f"lines {lines}")


truth = resonance_peak(PLANT)
print(f"truth: resonance {truth.frequency:.3f} Hz, {truth.peak_db:.3f} dB")

# 1. the multisine test
plan = plan_multisine(DT, 0.2, 25.0, period=512, lines="random-odd", rng=3, realisations=6,
                      periods=2, transient_periods=1)
u = random_multisine(plan, rng=4, crest="clip").values
y = simulate_lti(PLANT, u + 0.02 * u**3, DT, noise_std=0.02, rng=5)["y"]
bla = estimate_bla(Experiment.from_arrays(DT, u=u, y=y), plan)
d = bla.distortion
share = np.sum(bla.nonlinear_variance) / np.sum(bla.variance)
print(f"multisine: {plan.realisations} realisations x {plan.periods} periods, "
      f"{len(plan.excited)} excited lines, {plan.resolution:.4f} Hz apart")
print(f"  distortion: odd {d.odd_db:.1f} dB, even {d.even_db:.1f} dB, noise {d.noise_db:.1f} dB "
      f"(re output); nonlinear share of the BLA variance {100 * share:.0f} %")
fit, fits = select_ml_order(hold(bla), [(1, 0), (2, 0), (3, 0)])
for f in fits:
    print(f"  order {f.n_poles}/{f.n_zeros}: V = {f.cost:.1f}, expected {f.expected_cost:.1f} "
          f"+- {f.cost_std:.1f}, p = {f.p_value:.2g}")
numbers = acceptance_numbers(fit, phase_frequency=5.0, distortion=d)
show(numbers)
for c in judge(numbers, {"bandwidth_min": 10.0, "resonance_peak_max": 3.0,
                         "distortion_max": -30.0}):
    print(f"  acceptance {c.name} {c.limit}: {'pass' if c.passed else 'FAIL'} ({c.reason})")

# 2. a white-noise record: the LPM, and the Welch H1 read off its lines
u2 = np.random.default_rng(6).standard_normal(8192)
exp2 = simulate_lti(PLANT, u2, DT, noise_std=0.05, rng=7)
lpm = estimate_lpm(exp2, f_max=30.0)
fit2, _ = select_ml_order(hold(lpm), [(1, 0), (2, 0), (3, 0)])
print(f"LPM: {lpm.n_lines} lines, {fit2.n_lines} independent; order {fit2.n_poles}/"
      f"{fit2.n_zeros}, p = {fit2.p_value:.2g}")
show(acceptance_numbers(fit2, phase_frequency=5.0))
welch = resonance_peak(estimate_frf(exp2, method="welch"))
print(f"Welch H1 (default segments) read off its lines: {welch.frequency:.2f} Hz, "
      f"{welch.peak_db:.2f} dB")
