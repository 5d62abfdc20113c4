"""The whitened distance of the identifiability checks, a chunk at a time.

``_fir_energy`` gives ‖A(q)(x − y)‖² (zero before the start) without the
difference or the N-sample filtered copy ``scipy.signal.lfilter`` made; it
must equal that copy's energy whatever the chunk (also shorter than the
filter).
"""

import numpy as np
import pytest
import scipy.signal as sps

from servoid.estimate._diagnostics import _fir_energy


@pytest.mark.parametrize("n", [1, 3, 50, 4097])
@pytest.mark.parametrize("chunk", [2, 7, 1000, 1 << 16])
@pytest.mark.parametrize("order", [0, 1, 4])
def test_chunked_energy_is_the_filtered_energy(n, chunk, order):
    rng = np.random.default_rng(n + chunk + order)
    ar = np.r_[1.0, 0.4 * rng.standard_normal(order)]
    x, y = rng.standard_normal(n), rng.standard_normal(n)
    w = sps.lfilter(ar, [1.0], x - y)
    assert _fir_energy(ar, x, y, chunk) == pytest.approx(float(w @ w), rel=1e-13)
