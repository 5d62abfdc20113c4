"""An over-parameterised output-error fit names its cancelling pole–zero pairs."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy import signal

from servoid import ServoidWarning
from servoid.data import Experiment
from servoid.estimate import fit_oe


def _record(b, a, snr_db=30.0, n=1000, seed=0):
    rng = np.random.default_rng(seed)
    u = rng.standard_normal(n)
    y0 = signal.lfilter(b, a, u)
    y = y0 + rng.standard_normal(n) * y0.std() * 10 ** (-snr_db / 20)
    return Experiment.from_arrays(1.0, u=u, y=y)


SECOND = ([0.0, 0.1, 0.05], [1.0, -1.5, 0.7])  # poles 0.75 ± 0.37j, zero −0.5


def test_a_fit_two_orders_too_high_names_two_pairs_and_the_right_order():
    with pytest.warns(ServoidWarning, match="2 pole–zero pairs cancel within their "
                                            "uncertainty.*fit nb = 2, nf = 2"):
        est = fit_oe(_record(*SECOND), 4, 4, 1)
    (note,) = est.options["cancellations"]
    assert "pole " in note and "of its σ" in note


def test_the_right_order_and_a_close_but_resolved_pair_are_not_flagged():
    with warnings.catch_warnings():
        warnings.simplefilter("error", ServoidWarning)
        est = fit_oe(_record(*SECOND), 2, 2, 1)
        # a real pole at 0.9 and a zero at 0.8 (distance 0.1), resolved at 60 dB
        near = fit_oe(_record([0.0, 1.0, -0.8], np.polymul([1.0, -0.9], [1.0, -0.5]), 60.0),
                      2, 2, 1)
    assert "cancellations" not in est.options and "cancellations" not in near.options
