"""Time stamps of a long record are checked a chunk at a time.

The check must still name the first largest irregular step wherever the
chunks fall, and accept a uniform grid with float rounding.
"""

import numpy as np
import pytest

from servoid import DataError
from servoid.data import Experiment, _experiment

CHUNK = _experiment._CHUNK
N = 3 * CHUNK + 77


def _stamps():
    return np.arange(N) * 1e-3


@pytest.mark.parametrize("gap", [CHUNK - 1, CHUNK, 2 * CHUNK + 5])
def test_the_first_largest_gap_is_named(gap):
    t = _stamps()
    t[gap + 1 :] += 5e-3  # one step of 6 ms
    t[N - 10 :] += 5e-3  # a second, equal step later: the first is named
    with pytest.raises(DataError, match=rf"step {gap} \("):
        Experiment.from_arrays(y=np.zeros(N), time=t)


def test_a_uniform_long_grid_passes():
    exp = Experiment.from_arrays(y=np.zeros(N), time=_stamps())
    assert exp.dt == pytest.approx(1e-3, rel=1e-12)


def test_a_non_finite_stamp_in_a_late_chunk_is_refused():
    t = _stamps()
    t[N - 3] = np.nan
    with pytest.raises(DataError, match="non-finite"):
        Experiment.from_arrays(y=np.zeros(N), time=t)
