"""``method = "pnlss"`` with ``linear = "auto"``: the linear start is the linear model that
model choice picks on the part PNLSS fits (never on the part it holds out)."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

from servoid import OptionError
from servoid.data import load_experiment_spec, write_csv, write_experiment_spec
from servoid.datasets import load_daisy
from servoid.workflows import identify
from servoid.workflows._choice import auto_candidates
from servoid.workflows._examples import open_loop


@pytest.fixture(scope="module")
def kept_start(tmp_path_factory):
    folder = tmp_path_factory.mktemp("auto")
    # the examples' linear second-order plant, coloured noise, seed 0: model choice picks
    # n4sid on the fitted 750 samples and the guard keeps that start (E = F = 0)
    spec = open_loop(folder / "data", 0, kind="linear", coloured=True,
                     identify={"method": "pnlss", "degree": 2, "linear": "auto"})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the coloured noise's note: not what is tested here
        result = identify(spec, folder / "out")
    return result, spec, folder


def test_a_kept_start_is_the_linear_model_model_choice_picks_on_all_the_data(kept_start):
    result, _, folder = kept_start
    o = result.estimate.options
    assert o["held_out"]["kept"] == "the linear start"
    label = o["refit"]["by"]
    assert o["refit"]["samples"] == 1000 and o["degree"] == 1
    # that candidate fitted by its own method on all the estimation data, independently
    candidate = next(c for c in auto_candidates() if c.label == label)
    other = open_loop(folder / "other", 0, kind="linear", coloured=True,
                      identify={"method": candidate.method, **candidate.table})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        linear = identify(other, write=False).estimate.model
    u = np.random.default_rng(5).standard_normal(3000)
    mine = result.estimate.model.simulate(u)[1000:]
    theirs = np.asarray(linear.simulate(u), dtype=float).ravel()[1000:]
    # the same linear model in another realisation (balanced states, normalised signals):
    # the responses agree to rounding once the start's transient has died out (the
    # plant's poles lie inside |z| < 0.9, so 0.9^1000 ≈ 1e-46); an offset apart
    gap = float(np.std(mine - theirs))
    assert gap < 1e-8 * float(np.std(theirs))


def test_the_choice_is_said_in_the_result_the_report_and_results_json(kept_start):
    result, _, folder = kept_start
    choice = result.estimate.options["linear_choice"]
    assert choice["samples"] == 750  # the fitted part alone, never the held-out 250
    assert choice["reason"] and choice["chosen"] in {c["label"] for c in choice["candidates"]}
    assert choice["n_states"] == result.estimate.options["n_states"]
    page = (folder / "out" / "report.html").read_text(encoding="utf-8")
    assert "chosen by model choice among the linear candidates on 750 samples" in page
    saved = json.loads((folder / "out" / "results.json").read_text(encoding="utf-8"))
    assert saved["linear_choice"]["chosen"] == choice["chosen"]
    assert "model choice picks on all 1000 estimation samples" in \
        saved["estimate"]["options"]["held_out"]["why"]


def test_ball_and_beam_starts_from_the_continuous_model_not_n4sid(tmp_path):
    # DaISy ball and beam (an integrating plant), first half estimation, second validation,
    # as benchmarks/study_pnlss_real.py: its n4sid start is poor (PNLSS 54.11 % there,
    # results-pnlss-real.json); model choice picks a continuous tf with two poles
    exp = load_daisy("ballbeam").detrend("mean")
    half = exp.n_samples // 2
    write_csv(exp.slice(0, half), tmp_path / "est.csv")
    write_csv(exp.slice(half, None), tmp_path / "val.csv")
    u, y = exp.names_of("u")[0], exp.names_of("y")[0]
    path = tmp_path / "bb.toml"
    write_experiment_spec({"data": {"file": "est.csv"},
                           "channels": {"u": {"source": u, "role": "u"},
                                        "y": {"source": y, "role": "y"}},
                           "validation": {"file": "val.csv"},
                           "identify": {"method": "pnlss", "degree": 2, "monomials": "state",
                                        "linear": "auto"}}, path)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = identify(path, write=False)
    o = result.estimate.options
    assert o["linear_choice"]["chosen"].startswith("tf (n_poles=2)")
    # the study records 74.83 % (model choice's own tf, n_poles = 2, on this split); 1
    # point of room for a solver change, far above the n4sid start's 54.11 %
    assert result.validations[0].fit_percent > 73.8


@pytest.mark.parametrize(("table", "words"), [
    ({"linear": ["auto", "bla"]},
     '"bla" starts from the multisine test'),
    ({"linear": "auto", "n_states": 3},
     "the states are its order; n_states = 3 cannot be given with it"),
])
def test_refused_combinations_say_why(tmp_path, table, words):
    spec = open_loop(tmp_path, 0, identify={"method": "pnlss", **table})
    with pytest.raises(OptionError, match=words.replace("(", r"\(").replace(")", r"\)")):
        identify(spec, write=False)
    assert load_experiment_spec(spec)  # the file itself is fine: only the option is refused
