"""The feedback test of a long record sums its residuals a chunk of rows at a time.

The statistic, p-value and correlations must not depend on the chunk size
(the sums are the same up to rounding: 1e-9 relative), and a record several
chunks long must still be judged: open loop quiet, closed loop flagged.
"""

import numpy as np
import pytest

from servoid.bench import simulate_lti, simulate_lti_loop
from servoid.closedloop import _feedback, feedback_test
from servoid.models import TransferFunction

DT = 0.02
PLANT = TransferFunction([158.0], [1.0, 10.0, 158.0])
PI = TransferFunction([0.5 + 3.0 * DT, -0.5], [1.0, -1.0], DT)


def _u(n, seed):
    return np.repeat(np.sign(np.random.default_rng(seed).standard_normal(n // 2)), 2)


@pytest.mark.parametrize("loop", ["open", "closed"])
def test_chunked_sums_equal_one_chunk(monkeypatch, loop):
    n = 3 * _feedback._CHUNK + 1234
    if loop == "open":
        exp = simulate_lti(PLANT, _u(n, 1), DT, noise_std=0.1, rng=1)
    else:
        exp = simulate_lti_loop(PLANT, PI, _u(n, 2), DT, noise_std=0.1, rng=2)
    chunked = feedback_test(exp)
    monkeypatch.setattr(_feedback, "_CHUNK", 10 * n)
    whole = feedback_test(exp)
    assert chunked.statistic == pytest.approx(whole.statistic, rel=1e-9)
    np.testing.assert_allclose(chunked.cross_correlation, whole.cross_correlation, rtol=1e-9,
                               atol=1e-12)
    assert chunked.has_feedback == (loop == "closed")
