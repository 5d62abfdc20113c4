"""The demo's default test is one the actuator can run, and its verdict carries the checks."""

from __future__ import annotations

import warnings

import pytest

from servoid.plants.ehsa import SET_B, excitation_limits, run_demo


def test_demo_runs_a_feasible_test(tmp_path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        demo = run_demo(tmp_path / "demo")
    ex = demo.bench_run.excitation
    assert ex.amplitude == pytest.approx(0.19e-3)  # the spec's ±1 mm needs 35 MPa of 21
    assert excitation_limits(SET_B, ex).feasible
    assert not any("asks more than the actuator" in w for w in demo.bench_run.warnings)
    checks = {c.name: c for c in demo.verdict().checks}
    # linear bench data: neither the flow law nor the loop's DC gain departs
    assert checks["flow law"].outcome == "pass" and checks["DC gain"].outcome == "pass"
    assert "±0.19 mm" in str(demo)
    ident = demo.identification.to_dict()
    assert ident["flow_law"]["seen"] is False and ident["dc_gain"]["mismatch"] is False
