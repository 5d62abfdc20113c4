"""``method = "pnlss"``: a kept linear part is refitted on all the estimation data; the
linear start chosen per order between n4sid and OE on the held-out part."""

from __future__ import annotations

import json

import numpy as np
import pytest

from servoid import OptionError
from servoid.data import load_experiment_spec
from servoid.nonlinear import fit_pnlss
from servoid.workflows import identify
from servoid.workflows._examples import open_loop


def _linear_record(folder, seed, **identify_table):
    """The examples' linear second-order plant, coloured output noise (σ = 0.02 before the
    filter), 1000 estimation samples."""
    return open_loop(folder, seed, kind="linear", coloured=True,
                     identify={"method": "pnlss", "n_states": 2, "degree": 2,
                               "linear": "n4sid", **identify_table})


@pytest.fixture(scope="module")
def refitted(tmp_path_factory):
    folder = tmp_path_factory.mktemp("refit")
    # seed 2: the guard keeps the linear part refined by output error (E = F = 0)
    spec = _linear_record(folder / "data", 2)
    return identify(spec, folder / "out"), spec, folder / "out"


def test_a_kept_linear_part_is_the_output_error_fit_on_all_the_estimation_data(refitted):
    result, spec, _ = refitted
    o = result.estimate.options
    assert o["held_out"]["kept"] == "linear"
    estimation, _ = load_experiment_spec(spec).records()
    model = result.estimate.model
    # the same linear model class fitted by output error on all 1000 samples from another
    # start (OE), with the same output offset: the same minimum of the same cost
    other = fit_pnlss(estimation, 2, 1, linear="oe", offset=model.y_mean).model
    # the one fitted on the first 750 samples, as the guard kept it
    kept = fit_pnlss(estimation.slice(0, 750), 2, 2,
                     held_out=estimation.slice(750, None)).model
    u = np.random.default_rng(5).standard_normal(2000)
    gap = float(np.sqrt(np.mean((model.simulate(u) - other.simulate(u)) ** 2)))
    before = float(np.sqrt(np.mean((kept.simulate(u) - other.simulate(u)) ** 2)))
    # the search stops at a relative cost decrease of 1e-9: the two minima agree far below
    # the 750-sample fit's distance from them (measured 1.6e-14 against 3.2e-3)
    assert gap < 1e-6 and before > 1e-4
    assert o["refit"]["fitted_samples"] == 750 and o["refit"]["samples"] == 1000
    assert result.estimate.n_samples == 1000 and o["degree"] == 1


def test_the_refit_is_said_in_the_result_and_the_report(refitted):
    result, _, out = refitted
    why = result.estimate.options["held_out"]["why"]
    assert "refitted by output error on all 1000 estimation samples" in why
    assert "refitted on all the estimation data" in result.title
    page = (out / "report.html").read_text(encoding="utf-8")
    assert "refitted by output error on all 1000 estimation samples" in page
    saved = json.loads((out / "results.json").read_text(encoding="utf-8"))
    assert saved["estimate"]["options"]["refit"]["samples"] == 1000


def test_a_kept_n4sid_start_is_not_refitted_by_output_error(tmp_path):
    # seed 0: the n4sid start beat its own refinement by output error on the held-out part,
    # so output error is not what the held-out data chose: the model stays as kept
    result = identify(_linear_record(tmp_path, 0), write=False)
    o = result.estimate.options
    assert o["held_out"]["kept"] == "the linear start" and "refit" not in o
    assert result.estimate.n_samples == 750


def test_a_list_of_starts_chooses_each_orders_start_on_held_out_data(tmp_path):
    result = identify(_linear_record(tmp_path, 2, n_states=[1, 2], degree=[2],
                                     linear=["n4sid", "oe"]), write=False)
    rows = {(c.n_states, c.degree, c.linear): c for c in result.grid}
    # each order: its linear model (degree 1) from both starts, then degree 2 from the
    # start whose linear model scored lower on the held-out part
    for n in (1, 2):
        scores = {s: rows[n, 1, s].rms for s in ("n4sid", "oe")}
        assert (n, 2, min(scores, key=scores.get)) in rows
    assert len(rows) == 6


def test_bla_in_a_list_of_starts_is_refused_naming_the_key(tmp_path):
    spec = _linear_record(tmp_path, 0, linear=["n4sid", "bla"])
    with pytest.raises(OptionError, match=r"\[identify\] linear.*given alone"):
        identify(spec, write=False)
