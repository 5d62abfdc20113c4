"""Session fixtures of the closed-loop tests (the shared truth lives in ``loop_records``)."""

from __future__ import annotations

import numpy as np
import pytest
from loop_records import DT, LOOP, TRUTH, reference

from servoid.plants.ehsa import simulate_closed_loop


@pytest.fixture(scope="session")
def r() -> np.ndarray:
    return reference()


@pytest.fixture(scope="session")
def y_clean(r: np.ndarray) -> np.ndarray:
    """Noise-free output of the Tustin-exact closed loop."""
    return simulate_closed_loop(TRUTH, r, DT, LOOP)
