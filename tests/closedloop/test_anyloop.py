"""The any-plant closed-loop methods on loops they do not share (``anyloop_rigs``).

The default suite runs a reduced form of the study in ``anyloop_study``:
four seeds of 6000 samples per loop.  The study itself (100 seeds per loop)
is ``test_anyloop_study_100_seeds``, marked slow; its counts are in
``benchmarks/results-closedloop-any-study.json``.  It includes the motor loop
under its slow PRBS (50 ms bit), where the indirect and two-stage estimates
do not claim consistency: their covariance changes by more than ×1.4 within
one σ of the estimate (:mod:`servoid.closedloop._linearity`).
"""

from __future__ import annotations

import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent))

from anyloop_rigs import RIGS
from anyloop_study import fit, study

from servoid import IdentifiabilityError, ServoidWarning
from servoid.closedloop import (
    feedback_test,
    fit_cliv,
    fit_direct_bj,
    fit_two_stage,
)
from servoid.estimate import fit_bj, fit_iv

#: loop label → (rig, PRBS clock or None for the rig's own)
LOOPS = {"motor, fast PRBS": ("motor", 2), "unstable": ("unstable", None),
         "delay": ("delay", None)}


@pytest.mark.parametrize("loop", list(LOOPS))
@pytest.mark.parametrize("method", ["cliv", "bj", "indirect", "two-stage"])
def test_each_method_holds_where_it_claims_consistency(loop, method):
    rig, clock = LOOPS[loop]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ServoidWarning)
        tally = study(rig, range(4), 6000, (method,), clock=clock)[method]
    for o in tally.outcomes:
        assert not o.refused, o.error
        if o.claims:
            # consistent and its covariance right: every coefficient within 4σ of the truth
            assert o.held, (o.seed, o.z)
    claimed = sum(o.claims for o in tally.outcomes)
    if method == "two-stage" and rig == "unstable":
        assert claimed == 0  # an unstable OE predictor: it says so instead (next test)
    elif method == "two-stage" and rig == "motor":
        assert claimed >= 1  # stage 1 leaves slow errors on 3 of 4 seeds: it says so
    elif method == "indirect" and rig == "unstable":
        # seeds 0 and 2 of these 6000-sample records: a σ changes by more than ×1.4 one σ away
        # or at the closed-loop IV estimate, and it says so (10 of 12 claimed at 10 000 samples)
        assert claimed == 2
    else:
        assert claimed == 4


def test_two_stage_says_an_unstable_plant_breaks_it():
    rec = RIGS["unstable"].closed(0, 6000)
    with pytest.warns(ServoidWarning, match=r"two-stage estimate is not consistent on this "
                                            r"record: the plant is unstable \(the closed-loop IV "
                                            r"estimate has a pole at \|z\| = 1\.0[0-9]+\)"):
        est = fit_two_stage(rec.experiment(), 3, 3, 1)
    assert est.options["consistent"] is False
    assert 'use method = "cliv", or "indirect"' in est.options["broken_assumptions"][0]


def test_direct_bj_reaches_an_unstable_plant_that_plain_bj_cannot():
    rig = RIGS["unstable"]
    rec = rig.closed(3, 6000)
    truth = rig.theta()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ServoidWarning)
        est = fit_direct_bj(rec.experiment(), 3, 1, 1, 3, 1)
        try:
            plain = fit_bj(rec.experiment(), 3, 1, 1, 3, 1)
            plain_z = np.max(np.abs((plain.parameters[:6] - truth) / plain.std[:6]))
        except Exception:  # noqa: BLE001 — a refusal is the other way plain BJ fails here
            plain_z = np.inf
    assert est.options["predictor"].startswith("stabilised")
    z = (est.parameters[:6] - truth) / est.std[:6]
    assert np.all(np.abs(z) < 4), z  # 4σ, one record
    # the estimate is the unstable plant (true pole at |z| = 1.0305)
    pole = np.max(np.abs(np.roots(np.concatenate([[1.0], est.parameters[3:6]]))))
    assert 1.0 < pole < 1.06, pole
    assert plain_z > 4  # measured 5–30σ or a stalled search on these seeds


def test_direct_bj_without_a_reference_says_it_may_miss_an_unstable_plant():
    from servoid.data import Experiment

    rec = RIGS["unstable"].closed(1, 4000)
    with pytest.warns(ServoidWarning, match="the Box–Jenkins search met the unit circle"):
        est = fit_direct_bj(Experiment.from_arrays(rec.rig.dt, u=rec.u, y=rec.y), 3, 1, 1, 3, 1)
    assert est.options["consistent"] is False
    assert "record the reference r" in est.options["broken_assumptions"][0]


def test_direct_bj_keeps_the_box_jenkins_predictor_on_a_stable_plant():
    rec = RIGS["delay"].closed(0, 6000)
    est = fit_direct_bj(rec.experiment(), 2, 1, 1, 2, 4)
    assert est.options["predictor"] == "box-jenkins"
    assert est.options["starts"] == ["default (IV on u)", "closed-loop IV"]


def test_two_stage_says_when_its_stage_1_error_shows():
    # motor loop, fast PRBS, seed 0: a FIR of AIC order leaves a slow error in û_r that the
    # stage-2 OE fits with a pole of its own (72σ from the truth); CLIV has no stage 1
    rig = RIGS["motor"]
    rec = rig.closed(0, 10_000, clock=2)
    with pytest.warns(ServoidWarning, match=r"the plant of stage 2 and the closed-loop IV "
                                            r"estimate of the same orders differ by [0-9.]+ σ"):
        est = fit_two_stage(rec.experiment(), 3, 3, 1)
    assert est.options["consistent"] is False
    assert np.max(np.abs((est.parameters - rig.theta()) / est.std)) > 10  # it is far off
    assert est.options["covariance"].startswith("two-step sandwich: stage-1 FIR error counted")


@pytest.mark.parametrize("method", ["indirect", "two-stage"])
def test_slow_prbs_through_a_fast_loop_is_not_claimed(method):
    # motor loop, 50 ms PRBS bit, seed 2: the fast poles (|z| = 0.53, 0.38) are barely seen;
    # the indirect and two-stage estimates land more than 4σ from the truth. Their covariance
    # changes by more than ×1.4 within one σ: they say so
    rec = RIGS["motor"].closed(2, 10_000)
    with pytest.warns(ServoidWarning, match=r"too little information about part of the "
                                            r"dynamics for the linearised intervals"):
        est = fit(method, rec)
    z = (est.parameters - rec.rig.theta()) / est.std
    assert np.max(np.abs(z)) > 4  # it is far off: without the check it would claim this
    assert est.options["consistent"] is False
    assert "a shorter reference bit" in est.options["broken_assumptions"][0]


def test_a_cliv_refusal_names_the_instruments_that_fail():
    # motor loop, a 1 s PRBS bit on 6 s of data: a few level changes cannot tell the output's
    # lags apart with any of the five filters of r (canonical correlation 0.052 with its lags)
    rec = RIGS["motor"].closed(0, 6000, clock=1000)
    with pytest.raises(IdentifiabilityError, match=r"with each of the 5 filters of the reference "
                                                   r"it tries .*The instruments that fail are "
                                                   r"those for y\(t−1\), y\(t−2\) and y\(t−3\)"):
        fit_cliv(rec.experiment(), 3, 3, 1)


def test_cliv_chooses_a_filter_of_r_where_the_default_instruments_fail():
    # motor loop under a 0.5 s PRBS bit: the default auxiliary ARX(12, 13) model r → u (and the
    # plain lags of r) make instruments nearly collinear (condition number 1.1e10), so fit_iv
    # refuses; an ARX(4, 5) filter of the same reference carries the plant
    rig = RIGS["motor"]
    exp = rig.closed(5, 10_000, clock=500).experiment()
    with pytest.raises(IdentifiabilityError, match="uncorrelated"):
        fit_iv(exp, 3, 3, 1, instrument="r", iterations=1)
    est = fit_cliv(exp, 3, 3, 1)
    assert est.options["instruments"] == "r through an ARX(4, 5) model of r → u"
    assert "the default auxiliary ARX model r → u: refused" in est.options["instrument_choice"]
    assert est.options["consistent"] is True
    z = (est.parameters - rig.theta_arx()) / est.std
    assert np.all(np.abs(z) < 4.0), z  # 4σ: consistent, and its covariance is the IV's own


def test_cliv_says_which_instruments_it_chose_on_a_good_record():
    est = fit_cliv(RIGS["delay"].closed(0, 6000).experiment(), 2, 2, 4)
    assert est.options["instrument_choice"].startswith(
        f"instruments: {est.options['instruments']}, chosen as the strongest of the 5 filters")
    assert est.options["consistent"] is True


@pytest.mark.parametrize("rig", ["motor", "delay"])
def test_feedback_test_holds_its_level_on_open_loop_rigs(rig):
    p = np.array([feedback_test(RIGS[rig].open(seed, 4000).experiment()).pvalue
                  for seed in range(40)])
    # 40 open-loop records: at 1 % expect 0.4 alarms (P(>= 3) = 0.008); at 10 %, 4 (P(> 9) < 1 %)
    assert np.sum(p < 0.01) <= 2, np.sort(p)[:5]
    assert np.sum(p < 0.10) <= 9, np.sort(p)[:10]


#: the slow study's loops: the default suite's and the motor under its own slow PRBS
SLOW_LOOPS = {**LOOPS, "motor, slow PRBS": ("motor", None)}
#: (method, loop) pairs that claim no seed: the method says why instead
NO_CLAIMS = {("two-stage", "unstable"), ("two-stage", "motor, slow PRBS"),
             ("indirect", "motor, slow PRBS")}


@pytest.mark.slow
@pytest.mark.parametrize("loop", list(SLOW_LOOPS))
def test_anyloop_study_100_seeds(loop):
    rig, clock = SLOW_LOOPS[loop]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ServoidWarning)
        tallies = study(rig, range(100), 10_000, ("cliv", "bj", "indirect", "two-stage"),
                        clock=clock)
    for method, tally in tallies.items():
        c = tally.counts()
        if c["claimed"] == 0:
            assert (method, loop) in NO_CLAIMS, (method, c)
            continue
        # 100 seeds: 93 % held among the seeds a method claims; 95 % intervals cover 0.90–0.98
        # where a method claims at least 20 seeds (fewer: a share too coarse to judge). The
        # indirect approach is held to 0.88–0.99: on the delay loop the study's own noise draws
        # spread its errors 0.71–0.84 of the exact asymptotic σ, 1.07–1.17 with other draws
        # (anyloop_delay_seeds.py), so its coverage there is the seeds', not the covariance's
        low, high = (0.88, 0.99) if method == "indirect" else (0.90, 0.98)
        assert c["claimed_held"] >= 0.93 * c["claimed"], (method, c)
        if c["claimed"] >= 20:
            assert low <= c["coverage"] <= high, (method, c)
        assert c["refused"] <= 2, (method, c)  # measured: 1 of 100 (indirect, delay loop)
