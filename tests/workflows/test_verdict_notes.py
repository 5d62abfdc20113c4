"""The verdict and the notes come from the same numbers and never contradict each other.

Each case builds one :class:`~servoid.validate.ValidationReport` and reads
both the verdict's checks (:func:`validation_checks`) and the report's notes
(:meth:`ValidationReport.notes`) from it; every combination of fit sign,
independence, whiteness, noise model and closed loop must agree.
"""

from __future__ import annotations

import dataclasses
import itertools
import json

import numpy as np
import pytest

from servoid.bench import simulate_lti
from servoid.data import write_csv, write_experiment_spec
from servoid.models import TransferFunction
from servoid.validate import validate
from servoid.workflows import identify, load_results
from servoid.workflows._verdict import validation_checks

DT = 0.02
WN, ZETA = 2 * np.pi * 2.0, 0.3
PLANT = TransferFunction([WN**2], [1.0, 2 * ZETA * WN, WN**2])


@pytest.fixture(scope="module")
def rig(tmp_path_factory):
    """Two records of a servo with coloured (AR 0.8) output noise."""
    folder = tmp_path_factory.mktemp("rig")
    for k, seed in enumerate((3, 4)):
        u = np.repeat(np.sign(np.random.default_rng(seed).standard_normal(600)), 4)
        exp = simulate_lti(PLANT, u, DT, noise_std=0.02, noise_model=([1.0, 0.5], [1.0, -0.8]),
                           rng=seed)
        write_csv(exp, folder / f"run{k}.csv")
    return folder


def _toml(folder, name, identify_table):
    table = {"data": {"file": "run0.csv"},
             "channels": {"valve": {"source": "u", "role": "u", "unit": "V"},
                          "position": {"source": "y", "role": "y", "unit": "mm"}},
             "validation": {"file": "run1.csv"}, "identify": identify_table}
    path = folder / f"{name}.toml"
    write_experiment_spec(table, path, overwrite=True)
    return path


@pytest.fixture(scope="module")
def report(rig):
    """One real validation report to vary."""
    result = identify(_toml(rig, "base", {"method": "oe", "nb": 2, "nf": 2, "nk": 1}),
                      write=False)
    return result.validation


CASES = list(itertools.product((93.5, -12.0), (0.7, 1e-6), (0.5, 1e-40), (True, False),
                               (False, True), ("robust", "white")))


@pytest.mark.parametrize(("fit", "p_ind", "p_white", "noise_model", "causal", "covariance"),
                         CASES)
def test_checks_and_notes_read_the_same_numbers(report, fit, p_ind, p_white, noise_model,
                                                causal, covariance):
    residuals = dataclasses.replace(report.residuals, independence_pvalue=p_ind,
                                    whiteness_pvalue=p_white, causal=causal)
    case = dataclasses.replace(report, fit_percent=fit, residuals=residuals,
                               noise_model=noise_model)
    checks = {c.name: c for c in validation_checks(case, covariance=covariance)}
    notes = " | ".join(case.notes())

    fit_check = checks["simulation fit"]
    assert fit_check.value == f"{fit:.1f} %"
    assert (fit_check.outcome == "fail") == ("(negative)" in notes)
    if fit < 0:
        assert f"is {fit_check.value} (negative)" in notes  # the same number in both

    independence = checks["input–residual independence"]
    assert independence.value == f"p = {p_ind:.3g}"
    correlated = "the residuals correlate with the input" in notes
    assert (independence.outcome != "pass") == correlated
    if correlated:
        assert f"(p = {p_ind:.3g})" in notes
        # where the loop can feed coloured noise back, the note's own "or the data were
        # taken in closed loop" is what the check says, and it does not reject
        fed_back = causal and not noise_model and p_white < 0.01
        assert independence.outcome == ("caution" if fed_back else "fail")
        if fed_back:
            assert "or the data were taken in closed loop" in notes
            assert "comes back through the loop" in independence.meaning

    whiteness = checks["residual whiteness"]
    assert whiteness.value == f"p = {p_white:.3g}"
    if p_white > 0.01:
        assert whiteness.outcome == "pass" and "Ljung–Box" not in notes
    elif noise_model:
        assert whiteness.outcome == "caution"
        assert f"not white (Ljung–Box p = {p_white:.3g}): the noise model is rejected" in notes
    else:
        assert whiteness.outcome == "info"  # an output-error model: no rejection either side
        assert f"coloured (Ljung–Box p = {p_white:.3g})" in notes
        assert "this alone does not reject it" in notes
        assert "does not reject it" in whiteness.meaning
    # the sentence the demo's verdict used to print next to robust intervals
    assert not any("assume more than the data show" in c.meaning for c in checks.values())
    if covariance == "robust" and whiteness.outcome == "caution":
        assert "robust" in whiteness.meaning and "too narrow" not in whiteness.meaning


def test_the_written_report_and_results_carry_one_verdict(rig, tmp_path):
    """OE on coloured noise: accepted, and the box, the notes and results.json agree."""
    out = tmp_path / "oe"
    result = identify(_toml(rig, "oe", {"method": "oe", "nb": 2, "nf": 2, "nk": 1}), out)
    verdict = result.verdict()
    assert verdict.decision == "accept"
    whiteness = next(c for c in verdict.checks if c.name == "residual whiteness")
    assert whiteness.outcome == "info"
    assert any("this alone does not reject it" in n for n in result.notes)
    html = (out / "report.html").read_text(encoding="utf-8")
    box = html[html.index('<div class="box'):html.index("<h2>Experiment</h2>")]
    assert "ACCEPT — passes every check" in box and whiteness.meaning in box
    assert "NOT white" not in html
    data = json.loads((out / "results.json").read_text(encoding="utf-8"))
    assert data["verdict"] == json.loads(json.dumps(verdict.to_dict()))
    assert load_results(out / "results.json").summary.decision == "accept"
    assert "<b>ACCEPT</b> — passes every check" in result._repr_html_()  # a notebook shows it
    conditions = data["verdict"]["conditions"]
    assert [c["record"] for c in conditions] == ["estimation: run0.csv", "validation: run1.csv"]
    assert conditions[0]["sample_rate_hz"] == pytest.approx(1 / DT)  # 50 Hz, the record's
    assert conditions[0]["n_samples"] == 2400 and conditions[0]["channel"] == "valve"


def test_arx_on_coloured_noise_gives_the_reason_its_note_gives(rig):
    result = identify(_toml(rig, "arx", {"method": "arx", "na": 2, "nb": 2, "nk": 1}),
                      write=False)
    verdict = result.verdict()
    whiteness = next(c for c in verdict.checks if c.name == "residual whiteness")
    assert whiteness.outcome == "caution"
    note = next(n for n in result.notes if "Ljung–Box" in n)
    assert whiteness.value.split("= ")[1] in note and "noise model is rejected" in note
    assert verdict.decision in ("inconclusive", "reject")  # the independence test may reject too


def test_a_validation_of_the_true_plant_in_closed_loop_is_not_rejected(rig):
    """The caution case is real: coloured noise fed back makes the true plant 'correlated'."""
    from servoid.bench import simulate_lti_loop
    from servoid.models import c2d

    controller = TransferFunction([0.5 + 3.0 * DT, -0.5], [1.0, -1.0], DT)
    r = np.repeat(np.sign(np.random.default_rng(12).standard_normal(2000)), 2)
    data = simulate_lti_loop(PLANT, controller, r, DT, noise_std=0.1,
                             noise_model=([1.0, 0.3], [1.0, -0.9]), rng=12)
    truth = c2d(PLANT, DT, "zoh").to_polynomial("oe")
    case = validate(truth, data, input="u", closed_loop=True)
    assert not case.residuals.is_independent  # the test's own verdict on the true plant
    checks = {c.name: c for c in validation_checks(case)}
    assert checks["input–residual independence"].outcome == "caution"


def test_a_results_file_without_a_verdict_is_judged_from_its_numbers(rig):
    from servoid.report import to_jsonable
    from servoid.workflows._summary import verdict_of

    result = identify(_toml(rig, "old", {"method": "oe", "nb": 2, "nf": 2, "nk": 1}),
                      write=False)
    data = json.loads(json.dumps(to_jsonable(result.to_dict())))  # as results.json holds it
    assert verdict_of(data) == result.verdict()  # a file with its verdict keeps it whole
    for damaged in (None, {"checks": [{"name": "fit"}]}):  # older, or a damaged entry
        data["verdict"] = damaged
        rebuilt = verdict_of(data)
        checks = {c.name: c for c in rebuilt.checks}
        assert checks["simulation fit"].value == f"{result.validation.fit_percent:.1f} %"
        assert checks["input–residual independence"].outcome == "pass"
        assert rebuilt.decision == "accept"
