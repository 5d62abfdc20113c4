"""Other starts before a block structure is called wrong, and messages that say which case.

Records from a continuous plant simulated far above the rate (servoid.bench.simulate_lti)
through |x| (a Wiener plant), or an output that does not depend on the input at all.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy.signal import lfilter

from servoid import IdentifiabilityError
from servoid.bench import simulate_lti
from servoid.data import Experiment
from servoid.models import TransferFunction
from servoid.nonlinear import Saturation, _block_retry, fit_block_retrying

DT = 0.01
WN = 2 * np.pi * 1.5
PLANT = TransferFunction([WN**2], [1.0, 2 * 0.4 * WN, WN**2])


def _wiener_abs(seed):
    rng = np.random.default_rng(seed)
    u = np.repeat(rng.standard_normal(1000), 3)
    x = simulate_lti(PLANT, u, DT, rng=seed)["y"]
    y = np.abs(x) + lfilter([1.0], [1.0, -0.8], 0.02 * rng.standard_normal(u.size))
    return Experiment.from_arrays(DT, u=u, y=y)


def test_the_default_start_is_kept_when_it_works():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        est = fit_block_retrying(_wiener_abs(0), "wiener", output_nonlinearity="abs")
    assert est.options["start"] == "the default start"
    assert est.options["starts"] == [{"start": "the default start",
                                      "outcome": "stable linear block"}]


def test_a_stalled_default_start_is_retried_from_the_others(monkeypatch):
    # the default start made to end as the record did ("no more than chance"); the
    # other starts are real fits
    real = _block_retry.fit_block
    calls = []

    def stalled(data, structure, **kw):
        calls.append(kw)
        if len(calls) == 1:
            raise IdentifiabilityError(_block_retry.CHANCE + " (0.1 of 5)")
        return real(data, structure, **kw)

    monkeypatch.setattr(_block_retry, "fit_block", stalled)
    with pytest.warns(Warning, match="tried other starts.*the fit from the centre of"):
        est = fit_block_retrying(_wiener_abs(1), "wiener", output_nonlinearity="abs")
    assert est.options["start"] == "the centre of |x| at 0"
    assert est.options["starts"][0]["outcome"].startswith(_block_retry.CHANCE)
    assert abs(est["abs.center"]) < 0.05  # the true centre 0, to the noise (σ ≈ 0.005)


def test_every_start_at_chance_says_the_structure_cannot_explain_the_data():
    rng = np.random.default_rng(3)
    u = np.repeat(rng.standard_normal(800), 3)
    y = 0.1 * rng.standard_normal(u.size)  # the output ignores the input
    with pytest.raises(IdentifiabilityError, match="the structure cannot explain the data: "
                       "from the default start, the centre of .* and a continuous linear"):
        fit_block_retrying(Experiment.from_arrays(DT, u=u, y=y), "wiener",
                           output_nonlinearity="abs")


def test_other_failures_say_no_start_found_a_fit(monkeypatch):
    def failing(data, structure, **kw):
        raise IdentifiabilityError("the linear block integrates (test)")

    monkeypatch.setattr(_block_retry, "fit_block", failing)
    with pytest.raises(IdentifiabilityError, match="no start found a fit: the default start: "
                       "the linear block integrates"):
        fit_block_retrying(_wiener_abs(2), "wiener", output_nonlinearity="saturation")


def test_a_refusal_about_the_data_is_not_retried(monkeypatch):
    calls = []

    def refusing(data, structure, **kw):
        calls.append(kw)
        raise IdentifiabilityError("deadzone.lower is not determined: excite more")

    monkeypatch.setattr(_block_retry, "fit_block", refusing)
    with pytest.raises(IdentifiabilityError, match="not determined"):
        fit_block_retrying(_wiener_abs(2), "wiener", output_nonlinearity="deadzone")
    assert len(calls) == 1


def test_random_starts_are_tried_after_the_others_and_seeded(monkeypatch):
    # every named start made to stall; the random starts are real fits from seeded breakpoints
    real = _block_retry.fit_block
    calls = []

    def stalled_unless_random(data, structure, **kw):
        calls.append(kw)
        if not isinstance(kw.get("output_nonlinearity"), Saturation):
            raise IdentifiabilityError(_block_retry.CHANCE + " (0.1 of 5)")
        return real(data, structure, **kw)

    monkeypatch.setattr(_block_retry, "fit_block", stalled_unless_random)
    data = _wiener_abs(4)
    with pytest.warns(Warning, match="tried other starts.*the fit from random start 1"):
        est = fit_block_retrying(data, "wiener", output_nonlinearity="saturation",
                                 multistart=3, seed=7)
    assert [s["start"] for s in est.options["starts"]] == [
        "the default start", "a continuous linear block (2 poles)", "random start 1"]
    first = calls[2]["output_nonlinearity"]
    assert first.lower < first.upper  # breakpoints at sorted random quantiles of y
    calls.clear()
    with pytest.warns(Warning):
        again = fit_block_retrying(data, "wiener", output_nonlinearity="saturation",
                                   multistart=3, seed=7)
    assert calls[2]["output_nonlinearity"].parameters.tolist() == \
        first.parameters.tolist()  # the same seed, the same start
    np.testing.assert_array_equal(again.parameters, est.parameters)


def test_the_cannot_explain_message_counts_the_random_starts(monkeypatch):
    def chance(data, structure, **kw):
        raise IdentifiabilityError(_block_retry.CHANCE + " (0.1 of 5)")

    monkeypatch.setattr(_block_retry, "fit_block", chance)
    with pytest.raises(IdentifiabilityError, match="the structure cannot explain the data: "
                       "from the default start, .*a continuous linear block .* and 2 random "
                       "starts"):
        fit_block_retrying(_wiener_abs(2), "wiener", output_nonlinearity="abs", multistart=2)


def test_no_start_found_a_fit_suggests_more_starts_only_when_none_were_asked(monkeypatch):
    def failing(data, structure, **kw):
        raise IdentifiabilityError("the linear block integrates (test)")

    monkeypatch.setattr(_block_retry, "fit_block", failing)
    with pytest.raises(IdentifiabilityError, match="more starts: multistart = 10"):
        fit_block_retrying(_wiener_abs(2), "wiener", output_nonlinearity="saturation")
    with pytest.raises(IdentifiabilityError, match="random start 2: the linear") as info:
        fit_block_retrying(_wiener_abs(2), "wiener", output_nonlinearity="saturation",
                           multistart=2)
    assert "more starts" not in str(info.value)
