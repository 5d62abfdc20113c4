"""The integrator check reads the pole's confidence region, not a threshold on |F(1)|.

A slow, stable process sampled at Ts = 4 s (poles z ≈ 0.993 ± 0.013j and 0.955, as on a
process record) has |F(1)|/Σ|f| near 1e-6, which the old threshold (1e-3) refused as an
integrator; its poles lie well inside the unit circle by their own uncertainty. The record
comes from a continuous plant simulated far above the rate (servoid.bench.simulate_lti).
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from servoid.bench import simulate_lti
from servoid.data import Experiment
from servoid.models import TransferFunction
from servoid.nonlinear import fit_hammerstein

TS = 4.0
POLES_Z = (0.993 + 0.013j, 0.993 - 0.013j, 0.955)


def _slow_record(seed):
    s = [np.log(z) / TS for z in POLES_Z]
    den = np.real(np.poly(s))
    plant = TransferFunction([den[-1]], den)  # unit static gain
    rng = np.random.default_rng(seed)
    u = np.repeat(rng.uniform(-1.5, 1.5, 300), 10)  # held 40 s: the process is slow
    x = simulate_lti(plant, u + 0.3 * u**2, TS, rng=seed)["y"]
    return Experiment.from_arrays(TS, u=u, y=x + 0.01 * rng.standard_normal(u.size))


@pytest.mark.parametrize("seed", [1, 2])
def test_a_slow_stable_process_is_not_called_an_integrator(seed):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        est = fit_hammerstein(_slow_record(seed), "polynomial", nb=3, nf=3)
    poles = np.roots(est.model.linear.f[0])
    slow = poles[np.argmax(np.abs(poles))]
    # the slow pair recovered to 0.002 (the ZOH of the fine plant, not an exact OE(3,3)):
    assert abs(abs(slow) - abs(POLES_Z[0])) < 2e-3
    assert np.max(np.abs(poles)) < 1.0
