"""The verdict box: its decision follows its checks, and the page shows it whole."""

from __future__ import annotations

import re

import pytest

from servoid import OptionError
from servoid.report import (
    Check,
    Conditions,
    Figure,
    Page,
    Section,
    Table,
    Verdict,
    render_html,
)

PASS = Check("simulation fit", "96.8 %", "pass", "follows the output")
FAIL = Check("input–residual independence", "p = 1e-06", "fail", "dynamics not captured")
CAUTION = Check("residual whiteness", "p = 1e-40", "caution", "noise model rejected")
INFO = Check("notes", "2", "info", "listed under Notes")


@pytest.mark.parametrize(("checks", "decision"), [
    ((PASS, INFO), "accept"),
    ((PASS, CAUTION, INFO), "inconclusive"),
    ((PASS, CAUTION, FAIL), "reject"),
    ((FAIL,), "reject"),
    ((INFO,), "inconclusive"),  # nothing compared the model with data
    ((), "inconclusive"),
])
def test_the_decision_follows_the_checks(checks, decision):
    assert Verdict("a model", checks).decision == decision


def test_the_reason_names_the_checks_that_decide():
    verdict = Verdict("a model", (PASS, CAUTION, FAIL, INFO))
    assert verdict.reason == "input–residual independence p = 1e-06: dynamics not captured"
    assert Verdict("a model", (PASS, CAUTION)).reason == \
        "residual whiteness p = 1e-40: noise model rejected"
    assert Verdict("a model", (PASS, INFO)).reason == "passes every check: simulation fit 96.8 %"
    assert Verdict("a model", (PASS,)).line().startswith("ACCEPT — ")


def test_an_unknown_outcome_is_refused():
    with pytest.raises(OptionError, match="outcome must be one of 'pass', 'fail'"):
        Check("fit", "1 %", "good", "?")  # type: ignore[arg-type]


def test_a_verdict_round_trips_through_its_dict():
    conditions = Conditions("estimation: run0.csv", 1000.0, 10235, "prbs", "r", (0.78, 71.9),
                            "declared by the excitation")
    verdict = Verdict("a model", (PASS, CAUTION), (conditions,),
                      (Table(("spec number", "value"), (("bandwidth", "4.6"),), "Spec numbers"),))
    data = verdict.to_dict()
    assert data["decision"] == "inconclusive" and data["reason"] == verdict.reason
    again = Verdict.from_dict(data)
    assert again == verdict
    assert again.conditions[0].duration == pytest.approx(10.235)  # 10235 samples at 1 kHz


def test_the_box_opens_with_the_decision_and_holds_every_check():
    conditions = Conditions("estimation: run0.csv", 50.0, 2400, "", "valve", (0.167, 9.33),
                            "spectrum within 10 dB of its peak")
    section = Verdict("ARX (na = 2)", (PASS, FAIL, INFO), (conditions,)).section()
    html = render_html(Page("p", (section,)))
    assert '<div class="box reject">' in html
    decision = re.search(r'<p class="decision reject">([^<]*)</p>', html)
    assert decision and decision.group(1).startswith("REJECT — input–residual independence")
    for cell in ("simulation fit", "96.8 %", "FAIL", "dynamics not captured", "50 Hz",
                 "48 s (2400 samples)", "not stated", "0.167–9.33 Hz (valve, spectrum"):
        assert f">{cell}" in html, cell
    # a phone shows each row as a block, every cell labelled with its column
    assert 'data-label="what it says"' in html


def test_short_cells_and_identifiers_never_wrap():
    table = Table(("serial", "K", "error"), (
        ("SN-0001", "0.232122 ± 0.00015",
         "FileFormatError: the TDMS file is truncated; copy it from the logger again"),))
    html = render_html(Page("p", (Section("Units", tables=(table,)),)))
    assert re.search(r'<td data-label="serial" class="nw">SN-0001</td>', html)
    assert re.search(r'<td data-label="K" class="nw">0.232122 ± 0.00015</td>', html)
    assert '<td data-label="error">FileFormatError' in html  # prose still wraps


def test_figures_scroll_sideways_inside_the_page():
    html = render_html(Page("p", (Section("s", figures=(Figure("AAAA", "image/png", "c"),)),)))
    assert '<figure><div class="scroll"><img alt="c"' in html
    # on a phone a figure keeps a readable width and scrolls inside its own box
    assert re.search(r"@media screen and \(max-width: 700px\).*figure img \{ width: auto; "
                     r"max-width: 680px; min-width: 100%; \}", html, re.S)
