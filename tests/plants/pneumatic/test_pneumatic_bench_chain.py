"""End to end: the virtual pneumatic rig's default campaign through ``identify``.

``servoid bench pneumatic`` then ``servoid identify pneumatic.toml``, in
process: the default campaign (40 dB on every sensor channel, 16 bits, 2 kHz
anti-alias filter at 10 kHz, the hot-wire's 1 kHz lag and ±4 g/s range,
seed 0) must give the actuator back.  The records are the rig's own files,
not simulator output, so this checks that the campaign file carries what
the scheme must know about the rig (the hot-wire's lag, measured
derivatives, a u that passed the anti-alias filter) and that the steps use
it.  Observed errors (seed 0) are in brackets.
"""

from __future__ import annotations

import dataclasses
import json
import warnings

import numpy as np
import pytest

from servoid.data import load_experiment_spec
from servoid.plants.pneumatic import (
    KnownConstants,
    identify_critical_pressure,
    identify_sliding_friction,
    write_pneumatic_campaign,
)
from servoid.workflows import identify


@pytest.fixture(scope="module")
def chain(tmp_path_factory):
    folder = tmp_path_factory.mktemp("rig")
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the default campaign must raise no rig warning
        write_pneumatic_campaign(folder, seed=0)
    spec = load_experiment_spec(folder / "pneumatic.toml")
    ident = identify(spec, write=False)
    truth = json.loads((folder / "truth.json").read_text(encoding="utf-8"))
    return folder, ident, truth


def rel(ident, truth, name):
    return abs(getattr(ident.result.parameters, name) / truth[name] - 1.0)


def test_campaign_tells_the_scheme_about_the_rig(chain):
    _, ident, _ = chain
    table = dict(ident.spec.identify)
    assert table["derivatives"] == "measured" and table["valve_u_hold"] == "cubic"
    assert ident.result.known.mdot_sensor_bandwidth == 1000.0
    assert ident.result.derivatives == "measured"


def test_valve_within_p2(chain):
    _, ident, truth = chain
    # spec P2 tolerances (observed ≤ 0.01 %: the ZOH-exact anti-alias filter on the u
    # staircase and the cubic hold leave no discretisation bias at 10 kHz)
    assert rel(ident, truth, "k_v") < 0.005
    assert rel(ident, truth, "xi_v") < 0.03
    assert rel(ident, truth, "omega_v") < 0.02


def test_thermodynamics_and_flow(chain):
    _, ident, truth = chain
    p = ident.result.parameters
    # κ, R: 0.5 % (+0.12 %, −0.01 %; std 0.05 %, 0.06 %)
    assert rel(ident, truth, "kappa") < 0.005 and rel(ident, truth, "R") < 0.005
    # p_krit: 0.02 absolute, ≈ 3σ of the separable fit's std 0.0064 (Newey–West) (+0.005)
    assert abs(p.p_krit - truth["p_krit"]) < 0.02
    for k in range(1, 5):
        # 2 %: the supply edges follow p_krit's error (ad_2, ad_3 −0.33 %, the others 0.1 %)
        assert rel(ident, truth, f"ad_{k}") < 0.02, k


def test_friction(chain):
    _, ident, truth = chain
    # the 0.5 ms regime guard and the colour-robust velocity floor leave noise only:
    # d_k +0.05 %, c_k −0.11 %, F_haft −0.003 % (std 0.04 %, 0.09 %, 0.007 %); 2 % is the
    # budget the S6 fit tolerates (a 1 % friction error alone costs it up to 15 points)
    for name in ("d_k", "c_k", "F_haft"):
        assert rel(ident, truth, name) < 0.02, name
    # the threshold sits in the map's switching band, which the anti-alias filter
    # smears over ±0.5 ms (+0.43 %)
    assert rel(ident, truth, "v_krit") < 0.02


def test_s6_validation_fit_of_both_pressures(chain):
    _, ident, _ = chain
    fit = ident.result.validation.fit
    # the acceptance: ≥ 90 % on the held-back record (observed 98.9 %, 98.8 %)
    assert fit["p_I"] >= 90.0 and fit["p_II"] >= 90.0
    assert fit["x_k"] >= 90.0  # (99.0 %)


def test_flow_record_stays_inside_the_hot_wire_range(chain):
    folder, _, truth = chain
    # P4: peak |ṁ| ≤ 4 g/s on the flow test; no sample at the sensor's limit
    flow = load_experiment_spec(folder / "flow.toml").load()
    peak = max(np.abs(flow["mdot_I"]).max(), np.abs(flow["mdot_II"]).max())
    assert peak <= 0.98 * 4e-3  # below the steps' saturation threshold (observed 3.0 g/s)
    assert truth["tests"]["flow"]["hot_wire_saturation"] == {"mdot_I": 0.0, "mdot_II": 0.0}


def test_without_the_known_sensor_lag_p_krit_is_lost(chain):
    folder, ident, truth = chain
    flow = load_experiment_spec(folder / "flow.toml").load()
    blind = dataclasses.replace(ident.result.known, mdot_sensor_bandwidth=None)
    assert isinstance(blind, KnownConstants)
    # the static flow equation regressed on a lagged ṁ: the profile's minimum moves
    # from 0.25 to ≈ 0.48, far outside the 0.02 the lag-filtered regressors reach
    assert identify_critical_pressure(flow, blind)["p_krit"] > truth["p_krit"] + 0.15


def test_svf_derivatives_cannot_carry_the_friction_at_40_db(chain):
    folder, ident, truth = chain
    friction = load_experiment_spec(folder / "friction.toml").load()
    # 0.14 mm of position noise differentiated twice by the zero-phase SVF drowns the
    # viscous term (c_k −96 % observed): why the rig's campaign asks for "measured"
    step = identify_sliding_friction(friction, ident.result.known, v_krit=truth["v_krit"],
                                     derivatives="svf")
    assert abs(step["c_k"] / truth["c_k"] - 1.0) > 0.5
