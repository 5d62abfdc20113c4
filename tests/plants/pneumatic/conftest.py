"""Session fixtures of the multi-step tests (records from the simulator)."""

from __future__ import annotations

import numpy as np
import pytest
from pneumatic_records import NOISE, TRUTH, sine_response, to_record, valve_response

from servoid.plants.pneumatic import KnownConstants


@pytest.fixture(scope="session")
def known():
    return KnownConstants.from_parameters(TRUTH)


@pytest.fixture(scope="session")
def responses():
    """Noise-free responses: valve, P4 sine, sine with force, validation (2 Hz, 50 mm)."""
    return {
        "valve": valve_response(),
        "sine": sine_response(),
        "thermo": sine_response(force=60.0),
        "validation": sine_response(amplitude=0.05, freq=2.0),
    }


@pytest.fixture(scope="session")
def clean_records(responses):
    r = responses
    sine = to_record(r["sine"], "sine")
    return {"valve": to_record(r["valve"], "valve"), "thermo": to_record(r["thermo"], "thermo"),
            "flow": sine, "friction": sine, "validation": to_record(r["validation"],
                                                                     "validation")}


@pytest.fixture(scope="session")
def noisy_records(responses):
    rng = np.random.default_rng(2024)
    r = responses
    sine = to_record(r["sine"], "sine", NOISE, rng)
    return {"valve": to_record(r["valve"], "valve", NOISE, rng),
            "thermo": to_record(r["thermo"], "thermo", NOISE, rng),
            "flow": sine, "friction": sine,
            "validation": to_record(r["validation"], "validation", NOISE, rng)}
