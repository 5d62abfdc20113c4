"""Any plant in closed loop: detect the feedback, then identify it without bias.

A 2 Hz servo under a PI controller, coloured noise inside the loop. The
feedback test flags the record; open-loop OE on (u, y) is biased; direct BJ,
the two-stage method and closed-loop IV are not; with the controller known,
the indirect approach gets the plant from (r, y) alone.

Run: python examples/closed_loop_any_plant.py
"""

import numpy as np

from servoid.bench import simulate_lti_loop
from servoid.closedloop import feedback_test, fit_cliv, fit_indirect_tf, fit_two_stage
from servoid.datasets import load_daisy
from servoid.estimate import fit_bj, fit_oe
from servoid.models import TransferFunction, c2d

dt = 0.02
wn, zeta = 2 * np.pi * 2.0, 0.4
plant = TransferFunction([wn**2], [1.0, 2 * zeta * wn, wn**2])
pi = TransferFunction([0.5 + 3.0 * dt, -0.5], [1.0, -1.0], dt)     # kp = 0.5, ki = 3 /s
r = np.repeat(np.sign(np.random.default_rng(1).standard_normal(2000)), 2)
record = simulate_lti_loop(plant, pi, r, dt, noise_std=0.1,
                           noise_model=([1.0, 0.3], [1.0, -0.9]), rng=2)

print(feedback_test(record).message)
print("ball and beam (DaISy):", feedback_test(load_daisy("ballbeam")).message[:60], "…")

true = c2d(plant, dt, "zoh").to_polynomial("oe")
truth = np.concatenate([true.b[0], true.f[0][1:]])                  # b0, b1, f1, f2
print(f"\n{'method':<12} {'b0':>9} {'b1':>9} {'f1':>9} {'f2':>9}   worst |error|/σ")
print(f"{'truth':<12} " + " ".join(f"{v:9.5f}" for v in truth))
fits = {
    "oe (u → y)": fit_oe(record, 2, 2, 1),
    "bj (direct)": fit_bj(record, 2, 1, 1, 2, 1),
    "two-stage": fit_two_stage(record, 2, 2, 1),
    "indirect": fit_indirect_tf(record, pi, 2, 2, 1),
}
for name, est in fits.items():
    theta = est.parameters[:4]
    worst = np.max(np.abs(theta - truth) / est.std[:4])
    print(f"{name:<12} " + " ".join(f"{v:9.5f}" for v in theta) + f"   {worst:8.1f}")
cliv = fit_cliv(record, 2, 2, 1)                                      # ARX order: a1, a2, b0, b1
theta = np.concatenate([cliv.parameters[2:], cliv.parameters[:2]])
worst = np.max(np.abs(theta - truth) / np.concatenate([cliv.std[2:], cliv.std[:2]]))
print(f"{'cliv':<12} " + " ".join(f"{v:9.5f}" for v in theta) + f"   {worst:8.1f}")
