"""PNLSS guarded by held-out data: never worse there than its linear start (issue 27)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from test_pnlss import _free_run_rms, _record

from servoid import DataError, Experiment, OptionError, OptionTypeError, ServoidWarning
from servoid.estimate import fit_oe
from servoid.nonlinear import fit_pnlss
from servoid.workflows import identify
from servoid.workflows._examples import open_loop


def _split(rec: Experiment, share: float = 0.3) -> tuple[Experiment, Experiment]:
    cut = round(rec.n_samples * (1 - share))
    return rec.slice(0, cut), rec.slice(cut, None)


def test_where_the_nonlinear_terms_over_fit_the_held_out_data_keep_the_linear_model():
    # a linear plant, 300 samples, σ = 0.1: 60 parameters of degree 3 fit the noise
    noise = 0.1
    fit, held = _split(_record("linear", 1, noise, 300))
    fresh = _record("linear", 2, noise)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ServoidWarning)  # the unguarded run diverges
        free = fit_pnlss(fit, 2, 3)
        guarded = fit_pnlss(fit, 2, 3, held_out=held)
        # unguarded, the search over-fits: worse on the held-out part than the guarded model
        # (measured 0.110 against 0.090), and its free run on a fresh record diverges
        assert _free_run_rms(free.model, held) > 1.1 * _free_run_rms(guarded.model, held)
        assert not _free_run_rms(free.model, fresh) < 2 * noise
    h = guarded.options["held_out"]
    assert h["kept"] in ("linear", "the linear start") and "E = F = 0" in h["why"]
    assert not guarded.model.E.any() and not guarded.model.F.any()  # exactly the linear model
    # and that linear model is at the noise floor on a fresh record (measured 1.001 σ)
    assert _free_run_rms(guarded.model, fresh) < 1.05 * noise


def test_the_kept_iterate_is_never_worse_on_held_out_data_than_its_start():
    noise = 0.005
    fit, held = _split(_record("duffing", 1, noise, 1200))
    est = fit_pnlss(fit, 2, 3, held_out=held)
    h = est.options["held_out"]
    # the hardening spring needs the cubic terms: they are kept, and the score is ordered
    assert h["kept"] == "nonlinear"
    assert h["chosen"] < h["linear"] <= h["start"]
    # the reported score is the model's own free run on the held-out part (same computation,
    # summation order only)
    assert _free_run_rms(est.model, held) == pytest.approx(h["chosen"], rel=1e-9)
    # near the floor from 840 fitted samples (measured 1.13 σ)
    assert h["samples"] == held.n_samples and h["chosen"] < 1.2 * noise


def test_e_f_zero_is_the_oe_start_itself_when_its_offset_is_chosen():
    # the input around 1 (not 0) and the plant at rest at first: the output's mean is not
    # G(1)·ū, so only the offset G(1)·ū makes E = F = 0 the OE model fitted on the record
    base = _record("linear", 3, 0.01, 800)
    rec = Experiment.from_arrays(u=base["u"] + 1.0, y=base["y"] + _step(base.n_samples),
                                 dt=base.dt)
    fit, held = _split(rec)
    est = fit_pnlss(fit, 2, 3, linear="oe", max_iter=0, held_out=held)
    oe = fit_oe(fit, nb=2, nf=2, nk=1).model.transfer_function(0)
    gain = float(np.sum(oe.num) / np.sum(oe.den))
    assert est.options["held_out"]["offset"].startswith("G(1)")
    # a constant 2.0 from x = 0 (rest at ū) settles where the OE model does (2000 samples of
    # a 0.6-damped 8 Hz resonance at 50 Hz settle to ε; the rest is rounding)
    y = est.model.simulate(np.full(2000, 2.0))
    assert y[-1] == pytest.approx(2.0 * gain, rel=1e-9)


def _step(n: int) -> np.ndarray:
    """The linear plant of ``_record`` answering a unit step from rest (sampled as there)."""
    from scipy import signal

    w1 = 2 * np.pi * 8
    b, a, _ = signal.cont2discrete(([w1**2], [1, 0.6 * w1, w1**2]), 1 / 500.0, "zoh")
    return signal.lfilter(np.ravel(b), a, np.ones(10 * n))[::10]


def test_the_held_out_records_must_match_the_fitted_ones():
    fit, held = _split(_record("linear", 1, 0.01, 400))
    with pytest.raises(OptionTypeError, match="held_out"):
        fit_pnlss(fit, 2, 2, held_out=held["u"])
    other = Experiment.from_arrays(u=held["u"], y=held["y"], dt=2 * held.dt)
    with pytest.raises(DataError, match=r"held_out must be sampled as the fitted records"):
        fit_pnlss(fit, 2, 2, held_out=other)


def test_the_workflow_says_which_iterate_was_kept_and_why(tmp_path):
    spec = open_loop(tmp_path, kind="linear",
                     identify={"method": "pnlss", "n_states": [1, 2], "degree": 3,
                               "max_iter": 30})
    result = identify(spec, tmp_path / "out")
    assert result.grid[0].status.startswith("chosen: lowest held-out RMS")
    assert all(np.isfinite(c.rms) for c in result.grid[:1])
    held = result.estimate.options["held_out"]
    assert held["samples"] == 250 and held["why"]  # the last quarter of 1000 samples
    assert result.to_dict()["grid"][0]["kept"] == held["kept"]
    page = (tmp_path / "out" / "report.html").read_text(encoding="utf-8")
    assert "held-out samples (not fitted)" in page and "Best first" in page


@pytest.mark.parametrize(("value", "error", "words"), [
    (1.0, OptionError, r"\[identify\] holdout = 1 is the share"),
    (-0.1, DataError, r"\[identify\] holdout must be >= 0")])
def test_a_holdout_outside_zero_to_one_is_refused(tmp_path, value, error, words):
    spec = open_loop(tmp_path, kind="wiener", identify={"method": "pnlss", "holdout": value})
    with pytest.raises(error, match=words):
        identify(spec, write=False)


def test_a_grid_without_held_out_data_is_refused(tmp_path):
    spec = open_loop(tmp_path, kind="wiener",
                     identify={"method": "pnlss", "n_states": [1, 2], "holdout": 0})
    with pytest.raises(OptionError, match=r"grid.*holdout = 0 holds none out"):
        identify(spec, write=False)


def test_the_linear_stage_forms_the_linear_columns_alone_and_the_same_ones():
    from servoid.nonlinear._pnlss_fit import _Search

    rec = _record("duffing", 1, 0.005, n=600)
    start = fit_pnlss(rec, 2, 3, max_iter=0).model  # the linear start: E = F = 0
    un = np.ascontiguousarray((rec["u"][:, None] - start.u_mean) / start.u_scale)
    yn = (rec["y"] - start.y_mean) / start.y_scale
    search = _Search(start, [(un, yn)], 0.0)
    x0s = [np.array([0.3, -0.1])]
    H, g, r = search.normal_equations(start.parameters, x0s)
    H1, g1, r1 = search.normal_equations(start.parameters, x0s, linear=True)
    lin = np.setdiff1d(np.arange(H.shape[0]), search.ef)
    # the same columns by the same recursion (E = F = 0 adds exact zeros): the linear block
    # agrees to rounding, the rows and columns of E and F are not formed
    assert np.allclose(H1[np.ix_(lin, lin)], H[np.ix_(lin, lin)], rtol=1e-12, atol=0)
    assert np.array_equal(r1, r) and np.allclose(g1[lin], g[lin], rtol=1e-12, atol=0)
    assert not H1[search.ef].any() and not g1[search.ef].any()
