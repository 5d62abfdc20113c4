"""fit_ema against the bench's known parameters.

The bench is an independent generator of the data: it simulates the
actuator ten times faster than the drive, passes the analog sensors through
the logger's anti-alias filter and quantises everything, while fit_ema only
sees the logged samples and the equations.
"""

from __future__ import annotations

import numpy as np
import pytest
from ema_records import GEAR, LEAD, record, z_scores

from servoid import DataError, IdentifiabilityError
from servoid.plants.ema import TVC_EMA, EmaBench, fit_ema

AA = (4, 2000.0)


def _fit(exp, **kw):
    return fit_ema(exp, gear_ratio=GEAR, lead=LEAD, anti_alias=AA, **kw)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_errors_lie_within_four_std_on_a_few_seeds(seed):
    exp, truth, _ = record(seed)
    result = _fit(exp)
    # the default test identifies everything but the screw's damping
    assert [n for n in result.names if not result.identifiable[n]] == ["c_s"]
    for name, z in z_scores(result, truth):
        assert abs(z) < 4, (name, z)  # 4σ of the returned covariance


@pytest.mark.slow
def test_intervals_cover_the_truth_over_a_hundred_seeds():
    # each parameter's 95 % interval should hold the truth in about 95 of 100 runs; a
    # binomial(100, 0.95) falls below 85 with probability 1e-4.  Every parameter counts in
    # every run, identified or not: counting a parameter only where it was identified selects
    # the runs whose estimate came out large (c_s), which no interval can survive
    zs = {}
    for seed in range(100):
        exp, truth, _ = record(seed)
        for name, z in z_scores(_fit(exp), truth, every=True):
            zs.setdefault(name, []).append(z)
    for name, values in zs.items():
        z = np.array(values)
        assert np.max(np.abs(z)) < 4.5, name  # 1400 draws: 4.5σ has probability 1e-5 each
        assert np.mean(np.abs(z) < 1.96) >= 0.85, (name, np.mean(np.abs(z) < 1.96))
        assert abs(np.mean(z)) < 0.5, name  # bias below half a std (0.3 is 3σ of the mean)


@pytest.mark.parametrize("name", ["b_L", "L", "J_total"])
def test_the_replica_of_the_anti_alias_filter_matters(name):
    # without it the LVDT's group delay (0.1 ms) reads as a deflection proportional to the
    # speed (a viscous load force), and the current's as a lag behind the voltage and the
    # encoder: these parameters move by tens of their standard deviations
    exp, truth, _ = record(1)
    for aa, low, high in ((None, 10, np.inf), (AA, 0, 4)):
        result = fit_ema(exp, gear_ratio=GEAR, lead=LEAD, anti_alias=aa)
        z = (result[name] - truth[name]) / result.std[result.names.index(name)]
        assert low <= abs(z) < high, (aa, z)


def test_a_rigid_looking_screw_is_reported_not_identifiable():
    # a screw 30 times stiffer deflects 0.1 µm, under the LVDT's noise: k_s and the split of
    # the inertia are not identifiable, and the result says so instead of an interval
    stiff = EmaBench(params=TVC_EMA.with_(k_s=4.5e9, c_s=1e5))
    exp, truth, _ = record(1, stiff)
    result = _fit(exp)
    assert not result.identifiable["k_s"]
    row = next(r for r in result.rows() if r["name"] == "k_s")
    assert row["ci_low"] is None and row["ci_high"] is None
    assert any("deflection is hardly above the LVDT's noise" in n for n in result.notes)
    assert "not identifiable" in str(result)
    # the totals are still there
    assert result.identifiable["J_total"] and result.identifiable["T_c_total"]
    for name, z in z_scores(result, truth):
        assert abs(z) < 4, (name, z)


def test_a_noisy_lvdt_leaves_the_split_and_the_stiffness_unidentified():
    # 20 times the LVDT's noise: the deflection equation fits ~40 %, and the noise, fed to the
    # motor by the position loop, would bias m_L by about 3 std; the result does not claim it
    exp, truth, _ = record(2, EmaBench(position_noise=8e-5))
    result = _fit(exp)
    assert result.equations["deflection equation"]["fit_percent"] < 85
    for name in ("m_L", "J_m", "k_s", "b_L", "F_cL"):
        assert not result.identifiable[name], name
    for name, z in z_scores(result, truth):  # what is still claimed is right
        assert abs(z) < 4, (name, z)


def test_a_known_load_mass_gives_the_stiffness_directly():
    exp, truth, _ = record(2)
    result = _fit(exp, load_mass=truth["m_L"])
    assert "m_L" in result.given and result["m_L"] == truth["m_L"]
    free = _fit(exp)
    std = result.std[result.names.index("k_s")]
    assert std < free.std[free.names.index("k_s")]  # the mass no longer comes from δ̈
    assert abs(result["k_s"] - truth["k_s"]) < 4 * std


def test_without_voltage_the_motor_constant_must_be_given():
    exp, truth, _ = record(3)
    with pytest.raises(DataError, match="give motor_constant"):
        fit_ema(exp, gear_ratio=GEAR, lead=LEAD, voltage=None)
    result = _fit(exp, voltage=None, motor_constant=truth["K_m"], motor_constant_std=1e-3)
    assert "R" not in result.names and result.given == ("K_m",)
    for name, z in z_scores(result, truth):
        assert abs(z) < 4, (name, z)


def test_a_record_that_reverses_all_the_time_is_refused():
    # no sweep, a fast small multisine: the motion is never one-way for long
    exp, _, _ = record(1, sweep=0.0, amplitude=2e-4, f_min=10.0)
    with pytest.raises(IdentifiabilityError, match="one-way segments"):
        _fit(exp)


@pytest.mark.parametrize(("kwargs", "error", "match"), [
    ({"gear_ratio": 0.0}, DataError, "gear_ratio must be > 0"),
    ({"bandwidth": 2000.0}, DataError, "quarter of the Nyquist"),
    ({"order": 3}, DataError, "order must lie in 4..8"),
    ({"current": "i_a"}, KeyError, "i_a"),
    ({"max_relative_std": -1.0}, DataError, "max_relative_std must be > 0"),
])
def test_bad_options_are_refused(kwargs, error, match):
    exp, _, _ = record(1, duration=2.0)
    args = {"gear_ratio": GEAR, "lead": LEAD}
    args.update(kwargs)
    with pytest.raises(error, match=match):
        fit_ema(exp, **args)
