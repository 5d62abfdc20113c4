"""Rig data with an analog anti-alias filter: the structure is rejected, not silently wrong.

The rig's 4th-order Butterworth before the sampler adds dynamics that a
2nd-order plant model does not have.  Fitted as if it were not there, ω_n
comes out ~18σ low — and the validation's input–residual test says the
structure is rejected, so the narrow interval is not the last word.
Modelling the filter's low-frequency group delay (2.6131/ω_c for a 4th-order
Butterworth) as an input delay brings ω_n and ζ back within 4σ.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from servoid import ServoidWarning
from servoid.bench import simulate_lti
from servoid.estimate import fit_tf, modal_parameters
from servoid.models import TransferFunction
from servoid.validate import validate

DT = 0.01
WN, ZETA = 2 * np.pi * 3.0, 0.3
PLANT = TransferFunction([WN**2], [1.0, 2 * ZETA * WN, WN**2])
CUTOFF = 30.0  # Hz: 60 % of the Nyquist frequency
GROUP_DELAY = 2.6131 / (2 * np.pi * CUTOFF)  # Butterworth n = 4: Σ 1/sin((2k−1)π/8) / ω_c
SEEDS = range(6)


def _fits(delay: float) -> list[tuple[float, float, bool]]:
    out = []
    for seed in SEEDS:
        u = np.repeat(np.sign(np.random.default_rng(seed).standard_normal(1000)), 3)
        est_data, val_data = simulate_lti(PLANT, u, DT, anti_alias=CUTOFF, noise_std=0.01,
                                          rng=seed).split(0.5)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ServoidWarning)
            est = fit_tf(est_data, 2, 0, delay=delay)
        rows = {r.name: r for r in modal_parameters(est)}
        out.append(((rows["wn1"].value - WN) / rows["wn1"].std,
                    (rows["zeta1"].value - ZETA) / rows["zeta1"].std,
                    validate(est, val_data).residuals.is_independent))
    return out


def test_an_unmodelled_filter_biases_the_plant_and_the_data_say_so():
    fits = _fits(0.0)
    assert all(z_wn < -8 for z_wn, _, _ in fits)  # measured −17…−20σ: far outside the interval
    assert not any(independent for _, _, independent in fits)  # and every run is flagged


@pytest.mark.parametrize("quantity", [0, 1])
def test_the_filter_delay_in_the_model_removes_the_bias(quantity):
    fits = _fits(GROUP_DELAY)
    z = np.array([f[quantity] for f in fits])
    assert np.all(np.abs(z) < 4)  # 4σ of the delta-method std (measured |z| ≤ 2.6)
