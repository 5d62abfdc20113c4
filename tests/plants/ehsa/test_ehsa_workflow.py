"""identify() with method = "closedloop": experiment file → K, ω_hp, δ_hp and a report."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

from servoid import DataError, OptionError, ServoidWarning
from servoid.data import Experiment, write_csv, write_experiment_spec
from servoid.models import TransferFunction, c2d
from servoid.plants.ehsa import (
    ClosedLoopIdentification,
    FeedbackLoop,
    loop_from_table,
    reduced_plant,
)
from servoid.signals import prbs
from servoid.workflows import identify

TRUTH = {"K": 3451.7, "omega_hp": 163.3, "delta_hp": 0.249}  # spec §4, Set B reduced
DT = 1e-3


@pytest.fixture(scope="module")
def rig(tmp_path_factory):
    folder = tmp_path_factory.mktemp("ehsa")
    ex = prbs(11, clock=10, amplitude=1e-3, dt=DT)
    # A continuous loop driven by the logged DAC staircase, sampled exactly (zero-order hold):
    # what a rig without anti-alias filter records. The workflow's default discretisation
    # ("auto") detects the staircase and models it exactly; data from the Tustin map would
    # carry its (ω_hp·dt)²/12 = 0.22 % warp on omega_hp, 40σ at this record length.
    closed = FeedbackLoop(0.01, 0.01).close(reduced_plant(tuple(TRUTH.values())))
    y = c2d(closed, DT, "zoh").simulate(ex.values)
    rng = np.random.default_rng(11)
    y = y + np.std(y) / 10 ** (34 / 20) * rng.standard_normal(y.size)  # 34 dB output noise
    exp = Experiment.from_arrays(DT, r=ex.values, y=y, names={"r": "y_r", "y": "y"},
                                 units={"y_r": "m", "y": "m"})
    write_csv(exp, folder / "run.csv")
    (folder / "truth.json").write_text(json.dumps(TRUTH))
    return folder


def write_spec(folder, identify_table, loop=None, report=None):
    table = {
        "data": {"file": "run.csv", "time": "time"},
        "channels": {"y_r": {"role": "r", "unit": "m"}, "y": {"role": "y", "unit": "m"}},
        "preprocess": {"detrend": "mean"},
        "loop": {"c": 0.01, "F": 0.01} if loop is None else loop,
        "identify": identify_table,
        "report": {"truth": "truth.json"} if report is None else report,
    }
    path = folder / "run.toml"
    write_experiment_spec(table, path, overwrite=True)
    return path


def test_closed_loop_workflow_recovers_truth_and_writes_report(rig, tmp_path):
    result = identify(write_spec(rig, {"method": "closedloop"}), tmp_path / "out")
    assert isinstance(result, ClosedLoopIdentification)
    assert list(result.results) == ["indirect", "one-step"]
    est = result.estimate
    for name, true in TRUTH.items():
        k = est.names.index(name)
        # one-step OE is consistent under white output noise: error within 4σ of its covariance
        assert abs(est.parameters[k] - true) < 4 * est.std[k], name
    assert result.validation.fit_percent > 95  # 34 dB: noise ≈ 2 % of the signal
    assert result.truth == TRUTH
    names = {p.name for p in result.files}
    assert {"results.json", "report.html", "bode.png", "poles.png"} <= names
    data = json.loads((tmp_path / "out" / "results.json").read_text())
    assert data["primary_approach"] == "one-step"
    assert {r["name"] for r in data["parameters"]} == set(TRUTH)
    html = (tmp_path / "out" / "report.html").read_text()
    assert "data:image/png;base64," in html and "omega_hp" in html
    assert "one-step" in str(result)


def test_single_approach(rig):
    result = identify(write_spec(rig, {"method": "closedloop", "approach": "one-step"}),
                      write=False)
    assert list(result.results) == ["one-step"]


def test_unknown_approach_lists_valid(rig):
    with pytest.raises(OptionError, match=r"approach must be one of 'indirect', 'one-step', "
                                          r"'direct'; got 'two-step'"):
        identify(write_spec(rig, {"method": "closedloop", "approach": "two-step"}), write=False)


def test_missing_loop_says_what_to_add(rig):
    with pytest.raises(DataError, match=r"add \[loop\] with c = <forward gain>"):
        identify(write_spec(rig, {"method": "closedloop"}, loop={}), write=False)


def test_unknown_identify_key(rig):
    with pytest.raises(OptionError, match="unknown key.*theta"):
        identify(write_spec(rig, {"method": "closedloop", "theta": 1}), write=False)


def test_loop_table_with_dynamic_feedback():
    loop = loop_from_table({"c": 1.0, "F": {"num": [0.9], "den": [1 / 300, 1.0]}})
    assert isinstance(loop.F, TransferFunction) and loop.F.dt is None


def test_loop_table_unknown_key():
    with pytest.raises(OptionError, match="valid keys are c, F"):
        loop_from_table({"c": 1.0, "F": 1.0, "gain": 2})


@pytest.mark.parametrize(("reference", "hold"), [("command", "zoh"), ("readback", "bandlimited")])
def test_declared_rig_sets_the_model_and_the_result_states_it(reference, hold, tmp_path):
    from servoid.plants.ehsa import EhsaBench, run, write_bench_files

    bench = EhsaBench(snr_db=35.0, reference=reference)
    rec = run(bench, prbs(10, clock=10, amplitude=1e-3, dt=bench.dt), rng=3)
    toml = write_bench_files(rec, tmp_path / "rig")[1]
    result = identify(toml, tmp_path / "out")
    one = result.results["one-step"]
    assert one.intersample == hold and one.discretization == ("auto" if hold == "zoh"
                                                              else "bandlimited")
    if reference == "command":  # the declared filter and decimation are in the model
        assert one.advance == 10 and "anti-alias filter" in one.intersample_note
    # validation of every approach simulates from an initial state fitted to the record
    assert {v.initial for v in result.validations.values()} == {"estimate"}
    assert result.validation.fit_percent > 95  # 35 dB: noise ≈ 1.8 % of the signal
    assert f"intersample (one-step): {one.intersample_note}" in str(result)
    data = json.loads((tmp_path / "out" / "results.json").read_text())
    assert data["approaches"]["one-step"]["intersample"] == hold
    html = (tmp_path / "out" / "report.html").read_text()
    assert "intersample: reference taken as" in html


def _bench_toml(tmp_path, fidelity, **identify_extra):
    from servoid.plants.ehsa import EhsaBench, run, write_bench_files
    from servoid.signals import prbs

    bench = EhsaBench(fidelity=fidelity, reference="command")
    # seed 12: over seeds 20–39 the reduced record was rejected 0/20 times (the test's level is
    # 1 %; seed 11 happens to draw reference–residual p = 0.0013, a legitimate 1-in-300 event)
    record = run(bench, prbs(9, clock=10, amplitude=1e-3, dt=bench.dt), rng=12)
    files = write_bench_files(record, tmp_path / fidelity, format="csv")
    toml = next(p for p in files if p.suffix == ".toml")
    if identify_extra:
        text = toml.read_text().replace('method = "closedloop"', 'method = "closedloop"\n' + "\n".join(
            f"{k} = {v}" for k, v in identify_extra.items()))
        toml.write_text(text)
    return toml


@pytest.mark.parametrize(("fidelity", "rejected"), [("reduced", False), ("full", True)])
def test_the_structure_test_runs_in_the_workflow(tmp_path, fidelity, rejected):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ServoidWarning)
        ident = identify(_bench_toml(tmp_path, fidelity), write=False)
    test = ident.structure_test
    # reduced data lie in the reduced structure (no rejection at 1 %); the full-order plant's
    # valve lag is 1.5 ms, thousands of LR units on this record
    assert test is not None and test.rejected is rejected
    assert ident.to_dict()["structure_test"]["rejected"] is rejected
    assert ("structure test" in " ".join(ident.notes)) is rejected
    assert ("!structure test" in str(ident)) is rejected
    if not rejected:
        # without [loop] skew_tolerance: this record fixes the channel skew to σ_τ ≈ 11 µs, and
        # 1.96 σ_τ moves ω_hp by 2.4 reduced σ (seen): the assumption of no skew is stated in the
        # verdict with the numbers and the fix, without making the true structure inconclusive
        skew = ident.skew
        assert skew is not None and skew.fires and skew.worst == "omega_hp"
        verdict = ident.verdict()
        (check,) = [c for c in verdict.checks if c.name == "channel skew (assumed none)"]
        assert check.outcome == "info" and check.value.endswith("σ")
        assert "assume the reference and position channels are sampled together" in check.meaning
        assert "state [loop] skew_tolerance" in check.meaning and "with the skew free" in check.meaning
        assert ident.to_dict()["channel_skew"]["fires"] is True


def test_refine_true_adds_the_nonlinear_refinement(tmp_path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ServoidWarning)
        ident = identify(_bench_toml(tmp_path, "nonlinear", refine="true",
                                     structure_test="false"), write=False)
    ref = ident.refinement
    assert ref is not None and "F_c" in ref.estimate.names
    # the nonlinear model validates better than the linear one-step on held-back data
    assert ref.validation.fit_percent > ident.validation.fit_percent
    assert ident.to_dict()["nonlinear_refinement"] is not None


def test_refine_names_are_checked(tmp_path):
    with pytest.raises(OptionError, match="refine must be one of"):
        identify(_bench_toml(tmp_path, "reduced", refine='["viscosity"]'), write=False)


def _auto_toml(tmp_path, fidelity):
    """The bench record with ``structure = "auto"``, one-step only, no structure test."""
    toml = _bench_toml(tmp_path, fidelity, structure='"auto"', structure_test="false")
    toml.write_text(toml.read_text().replace('approach = ["indirect", "one-step"]',
                                             'approach = "one-step"'))
    return toml


def test_structure_auto_reports_the_refinement_it_decided_on(tmp_path, monkeypatch):
    """The decision (flow law and DC gain fire on the nonlinear bench) reaches the report.

    The refinement itself is replaced by a stand-in (the real one is the slow test below).
    """
    from types import SimpleNamespace

    import servoid.plants.ehsa._workflow as wf

    calls = []
    stand_in = SimpleNamespace(
        estimate=SimpleNamespace(names=("F_c",), parameters=np.array([1.0]),
                                 std=np.array([0.1])),
        validation=SimpleNamespace(fit_percent=97.5), notes=lambda: ("stand-in note",),
        to_dict=lambda: {"stand_in": True})

    def refine(*args, **kwargs):
        calls.append(kwargs)
        return stand_in

    monkeypatch.setattr(wf, "refine_after_linear", refine)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ServoidWarning)
        ident = identify(_auto_toml(tmp_path, "nonlinear"), write=False)
    assert len(calls) == 1 and ident.refinement is stand_in
    (why,) = [n for n in ident.notes if n.startswith("structure = auto: ")]
    assert "the flow-law check fired" in why and "refinement ran" in why
    assert "nonlinear refinement: stand-in note" in ident.notes
    (check,) = [c for c in ident.verdict().checks if c.name == "nonlinear refinement"]
    assert check.value == "97.5 %"
    assert ident.to_dict()["nonlinear_refinement"] == {"stand_in": True}


@pytest.mark.slow
@pytest.mark.parametrize("fidelity", ["nonlinear", "reduced"])
def test_structure_auto_end_to_end(tmp_path, fidelity):
    # ~15 s for the nonlinear record (the refinement runs), ~5 s for the reduced one
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ServoidWarning)
        ident = identify(_auto_toml(tmp_path, fidelity), tmp_path / "out")
    (why,) = [n for n in ident.notes if n.startswith("structure = auto: ")]
    if fidelity == "reduced":  # linear data: no check fires, no refinement
        assert ident.refinement is None and "the linear model stands" in why
        return
    ref = ident.refinement
    assert ref is not None and "refinement ran" in why and "F_c" in ref.estimate.names
    # the refined model validates better than the linear one on the held-back half (96.5 % vs
    # 86.3 % seen)
    assert ref.validation.fit_percent > ident.validation.fit_percent + 5.0
    html = (tmp_path / "out" / "report.html").read_text()
    assert "Nonlinear refinement" in html
    data = json.loads((tmp_path / "out" / "results.json").read_text())
    assert data["nonlinear_refinement"] is not None
