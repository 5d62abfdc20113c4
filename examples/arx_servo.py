"""ARX of a position servo: design a PRBS, rehearse, choose orders, validate.

Run: python examples/arx_servo.py [FOLDER]   (writes FOLDER/arx_servo_validation.png;
without FOLDER, into a new temporary folder)
"""

import sys
import tempfile
from pathlib import Path

import numpy as np
from scipy.signal import lfilter

from servoid.data import Experiment
from servoid.estimate import select_arx_order
from servoid.models import TransferFunction, c2d
from servoid.report import plot_validation
from servoid.signals import prbs, prbs_clock
from servoid.validate import validate

rng = np.random.default_rng(1)
dt = 0.005
# the servo: 4 Hz, ζ = 0.35, 2 mm/V (unknown to the identification)
omega = 2 * np.pi * 4
plant = TransferFunction([2e-3 * omega**2], [1.0, 2 * 0.35 * omega, omega**2])
truth = c2d(plant, dt, "zoh").to_polynomial("arx")

clock = prbs_clock(tau=1 / omega, dt=dt)  # bit time from the time constant (spec §3.1)
u = prbs(9, clock=clock, amplitude=1.0, periods=4, dt=dt).values
y = truth.simulate(u) + lfilter([1.0], truth.a, 2e-6 * rng.standard_normal(u.size))
exp = Experiment.from_arrays(dt, u=u, y=y, names={"u": "valve", "y": "position"},
                             units={"valve": "V", "position": "m"})
estimation, validation = exp.detrend().split(0.5)

selection = select_arx_order(estimation, na=range(1, 5), nb=range(1, 5), nk=(0, 1, 2),
                             criterion="mdl")
best = selection.best
print(f"PRBS clock {clock} samples; MDL picks na={best.na}, nb={best.nb}, nk={best.nk}")
print(selection.estimate)
report = validate(selection.estimate.model, validation)
print(report)
out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(tempfile.mkdtemp(prefix="servoid-arx-"))
out.mkdir(parents=True, exist_ok=True)
plot_validation(report, out / "arx_servo_validation.png", unit="m", overwrite=True)
print(f"figure: {out / 'arx_servo_validation.png'}")
