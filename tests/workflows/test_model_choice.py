"""Several families in one run, chosen on held-out data: method = [...] and "auto".

Records come from a continuous plant simulated far above the sample rate with anti-alias
filtering (servoid.bench.simulate_lti), optionally through a tanh after it (a Wiener plant),
with AR(1) coloured noise — no estimator's own model.
"""

from __future__ import annotations

import json
import math
import warnings

import numpy as np
import pytest
from scipy.signal import lfilter

from servoid import OptionError
from servoid.bench import simulate_lti
from servoid.data import Experiment, write_csv, write_experiment_spec
from servoid.models import TransferFunction
from servoid.workflows import identify
from servoid.workflows._choice import Candidate, Score, pick
from servoid.workflows._gate import output_power_pvalue

DT = 0.01
WN = 2 * np.pi * 2.0
PLANT = TransferFunction([WN**2], [1.0, 2 * 0.5 * WN, WN**2])
BLOCK = {"wiener", "hammerstein", "narx"}


def _rig(folder, wiener, seeds=(21, 22)):
    for k, seed in enumerate(seeds):
        rng = np.random.default_rng(seed)
        u = np.repeat(rng.standard_normal(1500), 2)
        x = simulate_lti(PLANT, u, DT, rng=seed)["y"]
        y = np.tanh(1.2 * x) if wiener else x
        y = y + lfilter([1.0], [1.0, -0.9], 0.01 * rng.standard_normal(u.size))
        write_csv(Experiment.from_arrays(DT, u=u, y=y), folder / f"run{k}.csv", overwrite=True)
    return folder


def _toml(folder, identify_table, name="choice"):
    path = folder / f"{name}.toml"
    write_experiment_spec({"data": {"file": "run0.csv"},
                           "channels": {"u": {"source": "u", "role": "u"},
                                        "y": {"source": "y", "role": "y"}},
                           "validation": {"file": "run1.csv"}, "identify": identify_table},
                          path, overwrite=True)
    return path


@pytest.fixture(scope="module")
def wiener_rig(tmp_path_factory):
    # seed 101: the higher-order correlations are silent on the linear models' residuals (an
    # odd nonlinearity under a symmetric input); only the output-power test sees it
    return _rig(tmp_path_factory.mktemp("wiener"), wiener=True, seeds=(101, 10_101))


@pytest.fixture(scope="module")
def linear_rig(tmp_path_factory):
    return _rig(tmp_path_factory.mktemp("linear"), wiener=False)


def test_a_list_of_methods_gives_one_leaderboard(wiener_rig, tmp_path):
    path = _toml(wiener_rig, {"method": ["arx", "oe", "wiener"], "oe": {"nb": 2, "nf": 2},
                              "wiener": {"output_nonlinearity": "polynomial"}})
    with pytest.warns(Warning):
        result = identify(path, tmp_path / "out")
    assert result.label == "wiener (polynomial)"  # the true family
    text = str(result)
    assert "model choice among 3 candidates" in text and "▶ wiener (polynomial)" in text
    data = json.loads((tmp_path / "out" / "results.json").read_text())
    rows = {c["label"]: c for c in data["choice"]["candidates"]}
    assert set(rows) == {"arx", "oe (nb=2, nf=2)", "wiener (polynomial)"}
    assert rows["wiener (polynomial)"]["chosen"] and data["method"] == "wiener"
    assert all(r["fit_seconds"] > 0 and r["n_parameters"] > 0 for r in rows.values())
    # 3000 samples of an open-loop plant: the fold fits are the whole-data fits (±2 points)
    assert abs(rows["wiener (polynomial)"]["refit_gap_points"]) < 2.0 and result.rankable
    assert len(rows["oe (nb=2, nf=2)"]["held_out_blocks"]) == 4  # one hold-out, four blocks
    assert data["choice"]["rankable"] is True
    assert rows["oe (nb=2, nf=2)"]["model"]["type"] == "polynomial"  # exportable
    # the validation record was not used to choose: the held-out scores are not its fits
    assert rows["oe (nb=2, nf=2)"]["held_out_fit_percent"] != \
        rows["oe (nb=2, nf=2)"]["validation_fit_percent"]
    page = (tmp_path / "out" / "report.html").read_text()
    assert "Model choice" in page and page.count("Leaderboard") == 1  # not again in the verdict
    assert (tmp_path / "out" / "candidates.png").is_file()
    assert (tmp_path / "out" / "candidates-bode.png").is_file()
    assert any(c.name == "model choice" for c in result.verdict().checks)


def test_auto_adds_the_nonlinear_families_on_a_wiener_plant(wiener_rig):
    with pytest.warns(Warning):
        result = identify(_toml(wiener_rig, {"method": "auto"}), write=False)
    assert "output-power test" in result.gate and "found a nonlinearity" in result.gate
    chosen = next(e for e in result.entries if e.label == result.label)
    assert chosen.score.candidate.method == "wiener"  # the true family
    # within 2 fit points of the best candidate on the validation record
    best = max(e.validation.fit_percent for e in result.entries if e.validation is not None)
    assert chosen.validation.fit_percent > best - 2.0


def test_auto_stays_linear_on_a_linear_plant(linear_rig):
    with pytest.warns(Warning):
        result = identify(_toml(linear_rig, {"method": "auto", "folds": 3}), write=False)
    assert "no nonlinear family" in result.gate
    assert all(e.score.candidate.method not in BLOCK for e in result.entries)
    chosen = next(e for e in result.entries if e.label == result.label)
    assert chosen.score.n_parameters >= 4  # a second-order plant: no first-order model
    assert "3 contiguous folds" in result.scheme.text


def test_an_unstable_candidate_is_never_chosen(linear_rig):
    # ARX(3, 3) on this record is stable; a candidate is marked by its own verdict: here the
    # rule is exercised on scores directly, and through a run that lists a failing candidate
    scores = [Score(Candidate("a", "arx", {}), 95.0, 1.0, 4, 0.1, "unstable"),
              Score(Candidate("b", "oe", {}), 90.0, 1.0, 4, 0.1, "ok")]
    chosen, _ = pick(scores, "one-se")
    assert chosen.candidate.label == "b"
    path = _toml(linear_rig, {"method": ["oe", "hammerstein"],
                              "hammerstein": {"input_nonlinearity": "deadzone"}}, "fail")
    with pytest.warns(Warning):
        result = identify(path, write=False)
    assert result.label.startswith("oe")


def test_the_one_standard_error_rule_prefers_the_simpler_model():
    near = [Score(Candidate("big", "oe", {}), 90.0, 1.5, 8, 0.1),
            Score(Candidate("small", "oe", {}), 89.0, 1.5, 4, 0.1),
            Score(Candidate("tiny", "oe", {}), 80.0, 1.5, 2, 0.1)]
    chosen, reason = pick(near, "one-se")
    assert chosen.candidate.label == "small" and "within one standard error" in reason
    assert pick(near, "best")[0].candidate.label == "big"
    assert pick([Score(Candidate("x", "oe", {}), math.nan, math.nan, 2, 0.1,
                       "failed: no")], "one-se")[0] is None


def test_workers_score_the_same_as_one_process(linear_rig):
    table = {"method": ["oe", "tf"], "oe": {"nb": 2, "nf": 2}}
    with pytest.warns(Warning):
        serial = identify(_toml(linear_rig, table, "w1"), write=False)
    with pytest.warns(Warning):
        parallel = identify(_toml(linear_rig, {**table, "workers": 2}, "w2"), write=False)
    assert [e.score.mean for e in serial.entries] == [e.score.mean for e in parallel.entries]


@pytest.mark.parametrize("table, match", [
    ({"method": []}, "lists no method"),
    ({"method": ["oe", "nope"]}, "nope"),
    ({"method": ["oe"], "oe": {"nb": 2, "bogus": 1}}, r"\[identify.oe\].*bogus"),
    ({"method": ["oe"], "oe": 3}, "must be a table"),
    ({"method": ["oe"], "arx": {"na": 2}}, "arx"),
    ({"method": ["oe"], "holdout": 1.5}, "holdout"),
    ({"method": ["oe"], "rule": "median"}, "rule"),
])
def test_bad_choice_tables_are_refused(linear_rig, table, match):
    with pytest.raises(OptionError, match=match):
        identify(_toml(linear_rig, table, "bad"), write=False)


def test_export_takes_the_chosen_or_a_named_candidate(wiener_rig, tmp_path):
    from servoid.cli import main
    from servoid.models import load_model

    path = _toml(wiener_rig, {"method": ["oe", "tf"], "oe": {"nb": 2, "nf": 2},
                              "tf": {"n_poles": 2}}, "export")
    with pytest.warns(Warning):
        identify(path, tmp_path / "out")
    results = tmp_path / "out" / "results.json"
    assert main(["export", str(results), "--to", "json", "--out",
                 str(tmp_path / "chosen.json")]) == 0
    assert main(["export", str(results), "--to", "json", "--candidate", "oe (nb=2, nf=2)",
                 "--out", str(tmp_path / "oe.json")]) == 0
    assert type(load_model(tmp_path / "oe.json")).__name__ == "PolynomialModel"
    assert main(["export", str(results), "--to", "json", "--candidate", "nope",
                 "--out", str(tmp_path / "x.json")]) != 0


def test_the_output_power_test_sees_an_odd_output_nonlinearity_and_holds_its_level():
    # residuals of the best linear approximation of tanh after a linear plant (odd: the
    # correlations with u² cannot see it) against those of the true linear model, AR(1) noise
    def record(seed, wiener):
        rng = np.random.default_rng(seed)
        u = np.repeat(rng.standard_normal(1000), 2)
        x = lfilter([0.0, 0.3], [1.0, -0.7], u)
        noise = lfilter([1.0], [1.0, -0.9], 0.05 * rng.standard_normal(u.size))
        y = (np.tanh(1.2 * x) if wiener else x) + noise
        yhat = np.polyval(np.polyfit(x, y, 1), x)  # the linear model that fits best
        return y - yhat, yhat, u

    assert output_power_pvalue(*record(0, wiener=True)) < 1e-9  # a strong effect: p tiny
    alarms = sum(output_power_pvalue(*record(s, wiener=False)) < 0.01 for s in range(40))
    assert alarms <= 3  # 1 % level: P(≥ 4 of 40) < 0.001
    assert math.isnan(output_power_pvalue(np.zeros(100), np.ones(100), np.ones(100)))


@pytest.fixture(scope="module")
def noisy_rig(tmp_path_factory):
    # the linear plant with strong, slowly drifting noise (AR(1), pole 0.98): an ARX model
    # predicts that noise a few steps ahead; an OE model simulates the plant without bias
    folder = tmp_path_factory.mktemp("noisy")
    for k, seed in enumerate((31, 32)):
        rng = np.random.default_rng(seed)
        u = np.repeat(rng.standard_normal(1500), 2)
        x = simulate_lti(PLANT, u, DT, rng=seed)["y"]
        y = x + lfilter([1.0], [1.0, -0.98], 0.05 * rng.standard_normal(u.size))
        write_csv(Experiment.from_arrays(DT, u=u, y=y), folder / f"run{k}.csv", overwrite=True)
    return folder


@pytest.mark.parametrize(("purpose", "winner"), [("simulation", "oe"), ("prediction", "arx")])
def test_the_purpose_decides_between_simulation_and_prediction(noisy_rig, purpose, winner):
    # equal parameter counts: the rule takes the better score, and the score is the purpose's
    # (measured held-out fits: free run OE 48.3 ± 3.5 against ARX 23.5 ± 5.0 %; 5-step
    # prediction ARX 60.8 ± 2.4 against OE 48.3 % — wide margins, several standard errors)
    table = {"method": ["oe", "arx"], "oe": {"nb": 2, "nf": 2}, "arx": {"na": 2, "nb": 2},
             "purpose": purpose, "horizon": 5}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = identify(_toml(noisy_rig, table, purpose), write=False)
    assert result.label.startswith(winner)
    words = ("free-run simulation" if purpose == "simulation" else "5-step prediction")
    assert words in result.reason and words in result.scheme.text
    assert result.to_dict()["choice"]["purpose"] == purpose


def _with_stalled_oe(rig, monkeypatch, on_folds):
    """["oe", "arx"] whose OE fits after the scoring stall: on the whole estimation data, and
    on the folds too when `on_folds`; the result and its OE entry."""
    from servoid import ConvergenceError
    from servoid.workflows import _leaderboard
    from servoid.workflows._choice import _HeldSpec

    real = _leaderboard.get_method

    class Stalling:
        def __init__(self, method):
            self._method = method

        def run(self, spec, *args, **kwargs):
            if on_folds or not isinstance(spec, _HeldSpec):
                raise ConvergenceError("the search stalled (a test's stand-in)")
            return self._method.run(spec, *args, **kwargs)

    monkeypatch.setattr(_leaderboard, "get_method",
                        lambda name: Stalling(real(name)) if name == "oe" else real(name))
    path = _toml(rig, {"method": ["oe", "arx"], "oe": {"nb": 2, "nf": 2},
                       "arx": {"na": 1, "nb": 1}}, f"stalled{int(on_folds)}")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = identify(path, write=False)
    return result, next(e for e in result.entries if e.label.startswith("oe"))


def test_a_chosen_model_whose_whole_fit_fails_is_passed_over(linear_rig, monkeypatch):
    # OE scored on its fold, but (here, by construction) no later fit of it succeeds: the run
    # takes the next choice and says so, instead of failing with the OE error
    result, oe = _with_stalled_oe(linear_rig, monkeypatch, on_folds=True)
    assert result.label.startswith("arx")
    assert "oe (nb=2, nf=2) scored better but failed" in result.reason
    assert oe.result is None and "stalled" in oe.error


def test_auto_adds_the_closed_loop_candidates_when_the_file_declares_a_loop(tmp_path):
    # a reference channel declares the loop; [loop] open = true takes it back
    import dataclasses
    from types import MappingProxyType

    from servoid.data import load_experiment_spec
    from servoid.workflows._choice import candidates_of
    from servoid.workflows._examples import closed_loop

    spec = load_experiment_spec(closed_loop(tmp_path, identify={"method": "auto"}))
    labels = [c.label for c in candidates_of(spec, {})]
    assert [c for c in labels if c.startswith("closedloop-auto")] == [
        "closedloop-auto (nb=1, nf=1)", "closedloop-auto (nb=2, nf=2)",
        "closedloop-auto (nb=3, nf=3)"]
    assert "oe (nb=2, nf=2, nk=1)" in labels  # the linear set stays
    opened = dataclasses.replace(spec, loop=MappingProxyType({"open": True}))
    assert not any(c.method == "closedloop-auto" for c in candidates_of(opened, {}))


@pytest.mark.slow
def test_auto_scores_the_closed_loop_candidates_like_the_others(tmp_path):
    from servoid.workflows._examples import closed_loop

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = identify(closed_loop(tmp_path, identify={"method": "auto"}), write=False)
    loop = [e for e in result.entries if e.score.candidate.method == "closedloop-auto"]
    assert len(loop) == 3 and all(e.score.status == "ok" for e in loop)
    assert all(math.isfinite(e.score.mean) and e.validation is not None for e in loop)
    rows = result.to_dict()["choice"]["candidates"]
    assert sum(r["method"] == "closedloop-auto" for r in rows) == 3


def test_a_fit_that_changes_with_its_samples_is_said_to_leave_the_choice_unranked():
    # the ball-and-beam pattern (benchmarks/results-model-choice-real.json): the chosen model
    # fitted on the fold simulates those samples at 89 %, the one fitted on all the data at 0.3 %
    from servoid.workflows._choice import REFIT_TOLERANCE, refit_gap
    from servoid.workflows._leaderboard import Entry, _reproducibility

    shaky = Score(Candidate("tf2", "tf", {}), 42.0, 28.0, 4, 0.1, fold_fits=(89.2,))
    other = Score(Candidate("tf3", "tf", {}), -91.0, 70.0, 6, 0.1, fold_fits=(-10.0,))
    steady = Score(Candidate("oe2", "oe", {}), 30.0, 5.0, 4, 0.1, fold_fits=(30.0, 32.0))
    assert refit_gap(shaky, [0.3]) == pytest.approx(-88.9)  # exact arithmetic: 0.3 − 89.2
    assert refit_gap(steady, [29.0, math.nan]) == pytest.approx(-1.0)  # the NaN fold left out
    assert math.isnan(refit_gap(Score(Candidate("x", "oe", {}), 1.0, 1.0, 2, 0.1), [5.0]))
    entries = [Entry(shaky, refit_gap=refit_gap(shaky, [0.3])),
               Entry(other, refit_gap=refit_gap(other, [27.2])),
               Entry(steady, refit_gap=refit_gap(steady, [29.0, 31.0]))]
    caveat = _reproducibility(entries, shaky)
    assert "cannot rank these candidates" in caveat and "89.2 %" in caveat and "0.3 %" in caveat
    assert "1 other candidate too" in caveat and "tf3 +37.2" in caveat
    assert _reproducibility(entries, steady) == ""  # a reproducible choice keeps its reason
    assert abs(entries[2].refit_gap) < REFIT_TOLERANCE


def test_a_whole_fit_that_fails_returns_the_scored_fold_model(linear_rig, monkeypatch):
    # OE converges on its fold but (here, by construction) not on the whole estimation data:
    # the model the held-out data scored is returned, fitted on the fold, and the reason says
    # so — before, the next candidate was chosen instead (as in the test above)
    result, oe = _with_stalled_oe(linear_rig, monkeypatch, on_folds=False)
    assert result.label.startswith("oe")
    assert "failed (the search stalled" in result.reason and "is returned" in result.reason
    assert oe.fitted_on == "fold 1" and "stalled" in oe.error
    # 3000 samples, 30 % held out: the returned model was fitted on the 2100 others
    assert result.estimate.n_samples == 2100
    # the returned model is the scored one: its refit gap is 0 (to rounding) and it ranks
    assert abs(oe.refit_gap) < 1e-6 and result.rankable
    assert "ok; the model of fold 1" in str(result)  # the leaderboard marks it too
    row = next(r for r in result.to_dict()["choice"]["candidates"] if r["label"] == oe.label)
    assert row["fitted_on"] == "fold 1"


def test_a_quiet_held_block_does_not_dominate_the_score():
    # four held blocks with the same error, the first where the output barely moves: on the
    # held part's common scale the four block fits are equal; each block's own spread as the
    # scale (as before) scored the quiet block at about −900 %
    from types import SimpleNamespace

    from servoid.workflows._choice import _block_fits

    rng = np.random.default_rng(5)
    y = np.concatenate([0.01 * rng.standard_normal(100), rng.standard_normal(300)])
    error = np.where(np.arange(400) % 2, 0.1, -0.1)
    report = SimpleNamespace(first=0, measured=y, simulated=y - error)
    fits = _block_fits(report, prediction=False)
    assert len(fits) == 4 and np.ptp(fits) < 1e-9  # equal errors, equal scores
    assert fits[0] == pytest.approx(100 * (1 - 0.1 / np.std(y)))


def test_in_a_declared_loop_the_fits_of_u_y_as_if_open_are_not_chosen(tmp_path):
    # the reference channel declares the loop; held-out data from that loop cannot show OE's
    # feedback bias (seed 301: OE(2, 2) 67.7 % held out against BJ's 67.4 %, so the simpler OE
    # was chosen before), and the direct BJ is consistent there
    from servoid.workflows._examples import closed_loop

    table = {"method": ["oe", "bj"], "oe": {"nb": 2, "nf": 2},
             "bj": {"nb": 2, "nf": 2, "nc": 1, "nd": 1}}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = identify(closed_loop(tmp_path / "both", 301, identify=table), write=False)
        alone = identify(closed_loop(tmp_path / "open", 301,
                                     identify={"method": ["oe", "arx"]}), write=False)
    assert result.label.startswith("bj")
    oe = next(e for e in result.entries if e.label.startswith("oe"))
    assert oe.score.status.startswith("passed over: fits (u, y) as if open")
    # with no consistent candidate among them the open-loop fits are still compared
    assert all(e.score.status == "ok" for e in alone.entries)
