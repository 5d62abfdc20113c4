"""A free run that diverges on a validation record is named, with its sample."""

from __future__ import annotations

import pickle

import numpy as np
import pytest

from servoid import Experiment, ModelError, SimulationDivergedError
from servoid.validate import validate


class _Diverges:
    """A replayable model whose simulation leaves the finite numbers at sample 50."""

    dt = 0.1
    has_noise_model = False

    def replay(self, y, u, *, initial="auto"):
        out = np.ones_like(y)
        out[50:] = np.inf
        return out, 0, "zero"


def test_a_diverging_free_run_is_its_own_error():
    rng = np.random.default_rng(0)
    record = Experiment.from_arrays(dt=0.1, u=rng.standard_normal(200),
                                    y=rng.standard_normal(200), name="run2")
    with pytest.raises(SimulationDivergedError, match="'run2' at sample 50 .t = 5 s.") as err:
        validate(_Diverges(), record)
    assert err.value.sample == 50
    assert isinstance(err.value, ModelError)  # callers catching ModelError still see it
    again = pickle.loads(pickle.dumps(err.value))  # travels between Dask processes
    assert again.sample == 50 and str(again) == str(err.value)


def test_an_unstable_model_that_leaves_the_floats_is_named_not_a_linear_algebra_error():
    # a pole at z = 3 on 2000 samples: its free responses overflow to inf, where the
    # initial-state least squares used to stop with LinAlgError ("SVD did not converge")
    from servoid.models import TransferFunction

    rng = np.random.default_rng(1)
    record = Experiment.from_arrays(dt=0.1, u=rng.standard_normal(2000),
                                    y=rng.standard_normal(2000), name="run3")
    model = TransferFunction([1.0], [1.0, -3.0], 0.1)
    with np.errstate(all="ignore"), pytest.raises(SimulationDivergedError, match="'run3'"):
        validate(model, record)
