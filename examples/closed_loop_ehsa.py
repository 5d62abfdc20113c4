"""The electro-hydraulic actuator in closed loop: all three approaches on a bench record.

Run: python examples/closed_loop_ehsa.py
"""

import warnings

from servoid import ServoidWarning
from servoid.plants.ehsa import EhsaBench, FeedbackLoop, identify_closed_loop, run
from servoid.signals import prbs

bench = EhsaBench(snr_db=30.0)                       # Set B, reduced loop, 30 dB
record = run(bench, prbs(11, clock=10, amplitude=1e-3, dt=bench.dt), rng=7)
truth = record.truth
raw = record.raw                                     # volts at 5 kHz, as the DAQ wrote them
gains = record.calibration()
exp = raw.calibrate(gains).decimate(bench.decimation).detrend()
estimation, validation = exp.select("yr_cmd", "y_pos").split(0.5)

loop = FeedbackLoop(c=truth.c, F=truth.F)
print(f"truth: K = {truth.K:.5g} 1/s, omega_hp = {truth.omega_hp:.5g} rad/s, "
      f"delta_hp = {truth.delta_hp:.4g}")
for approach, options in [("indirect", {}), ("one-step", {"discretization": "prewarp"})]:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ServoidWarning)  # flags are listed below instead
        result = identify_closed_loop(estimation, loop, approach=approach, **options)
    print(f"\n{approach}:")
    print(result.estimate)
    for note in result.notes():
        print("  flagged:", note)
