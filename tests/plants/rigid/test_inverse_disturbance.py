"""Loop disturbances: measured force pulses and a reference offset in the rigid loop.

The known answer comes from an independent simulation of the same axis and
controller: ``scipy.integrate.solve_ivp`` (DOP853) integrates the friction
ODE between samples, stopping at every velocity zero to decide stick or
slip, instead of servoid's closed-form exponential steps.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from servoid import ChannelError, DataError, OptionError, OptionTypeError
from servoid.data import Experiment, ExperimentSpec, load_experiment_spec
from servoid.plants.rigid import (
    CascadeController,
    RigidAxis,
    fit_closed_loop_oe,
    simulate_rigid_loop,
)
from servoid.workflows import identify

DT = 1e-3
CTRL = CascadeController(kp=160.18, kv=243.45, gtau=35.15, saturation=10.0)
AXIS = RigidAxis(95.0, 200.0, 20.0, -3.0)
EXAMPLE = Path(__file__).parents[3] / "examples" / "emps"


def _reference_loop(axis, ctrl, r, d, at_drive, offset, q0):
    """Same loop, plant integrated by solve_ivp with velocity-zero events."""
    m, fv, fc, off = axis.mass, axis.viscous, axis.coulomb, axis.offset
    q, v = q0, 0.0
    q1 = q2 = q0
    pos, force = np.empty(r.size), np.empty(r.size)
    for k in range(r.size):
        qdf = (q - q2) / (2 * DT)
        volt = float(np.clip(ctrl.kv * (ctrl.kp * (r[k] + offset - q) - qdf),
                             -ctrl.saturation, ctrl.saturation))
        pos[k] = q
        force[k] = ctrl.gtau * volt + (d[k] if at_drive else 0.0)
        q2, q1 = q1, q
        net = ctrl.gtau * volt + d[k] - off
        t = 0.0
        while t < DT:
            if v != 0.0:
                s = np.sign(v)
            elif abs(net) > fc:
                s = np.sign(net)
            else:
                break  # stuck until the next sample
            def rhs(_t, x, s=s, net=net):
                return [x[1], (net - fv * x[1] - s * fc) / m]

            def stop(_t, x, s=s):
                return s * x[1]
            stop.terminal, stop.direction = True, -1
            sol = solve_ivp(rhs, (t, DT), [q, v], method="DOP853", rtol=1e-12, atol=1e-15,
                            events=stop)
            if sol.status == 1:
                t = float(sol.t_events[0][0])
                q, v = float(sol.y_events[0][0][0]), 0.0
            else:
                q, v = float(sol.y[0, -1]), float(sol.y[1, -1])
                t = DT
    return pos, force


def _case(n=1500):
    t = DT * np.arange(n)
    # moves out and back (velocity reversals and stops), with 1 Hz force pulses of 5 V·gtau
    r = 0.02 * (1 - np.cos(2 * np.pi * 0.8 * t))
    pulses = np.where((t % 1.0) >= 0.3, 5.0 * CTRL.gtau, 0.0) * (t > 0.3)
    return r, pulses


@pytest.mark.parametrize(("at", "offset"), [("drive", 0.0), ("load", 0.0), ("drive", 2e-3)])
def test_disturbance_reproduces_an_independent_simulation(at, offset):
    r, d = _case()
    ref_q, ref_f = _reference_loop(AXIS, CTRL, r, d, at == "drive", offset, r[0] + offset)
    sim = simulate_rigid_loop(AXIS, CTRL, r, DT, disturbance=d, disturbance_at=at,
                              reference_offset=offset)
    scale_q = np.abs(ref_q - ref_q[0]).max()
    # both integrate the same ODE exactly (closed form vs DOP853 at rtol 1e-12, stopped at each
    # velocity zero): they agree to rounding (measured 1e-17 m, 5e-11 N); 1e-9 of the stroke and
    # of the force peak leaves room for the loop amplifying rounding over 1500 samples
    err_q = np.abs(sim.position - ref_q).max()
    err_f = np.abs(sim.force - ref_f).max()
    assert err_q < 1e-9 * scale_q
    assert err_f < 1e-9 * np.abs(ref_f).max()
    assert np.count_nonzero(sim.velocity == 0) > 0  # the case exercises stick as well as slip
    # without the disturbance channel the same loop misses the pulses: 0.4 % of the stroke in
    # position (measured), and the whole pulse height in the force
    blind = simulate_rigid_loop(AXIS, CTRL, r, DT, reference_offset=offset)
    assert np.abs(blind.position - ref_q).max() > 1e-3 * scale_q
    assert np.abs(blind.force - ref_f).max() > 0.5 * d.max()


@pytest.mark.parametrize(
    ("kwargs", "error", "match"),
    [
        ({"disturbance": np.ones(7)}, DataError, "one value per reference sample"),
        ({"disturbance": np.full(10, np.nan)}, DataError, "disturbance has 10 non-finite"),
        ({"disturbance": "pulses"}, OptionTypeError, "disturbance must be an array"),
        ({"disturbance": np.ones((10, 2))}, DataError, "disturbance must be 1-D"),
        ({"disturbance_at": "motor"}, OptionError, "disturbance_at must be one of"),
        ({"reference_offset": "1 mm"}, OptionTypeError, "reference_offset must be a number"),
        ({"reference_offset": np.inf}, DataError, "reference_offset must be finite"),
    ],
)
def test_simulate_rigid_loop_checks_the_loop_inputs(kwargs, error, match):
    with pytest.raises(error, match=match):
        simulate_rigid_loop(AXIS, CTRL, np.zeros(10), DT, **kwargs)


def test_a_load_disturbance_is_not_part_of_the_drive_force():
    r, d = _case(400)
    drive = simulate_rigid_loop(AXIS, CTRL, r, DT, disturbance=d, disturbance_at="drive")
    load = simulate_rigid_loop(AXIS, CTRL, r, DT, disturbance=d, disturbance_at="load")
    # the axis sees the same force either way: same motion (to rounding) ...
    np.testing.assert_allclose(load.position, drive.position, rtol=0, atol=1e-15)
    # ... and the drive force differs by exactly the disturbance (ε of the 240 N force)
    np.testing.assert_allclose(drive.force - load.force, d, rtol=0, atol=1e-9)


# -- the workflow: [loop] disturbance, disturbance_at, reference_offset ----------------------


@pytest.fixture(scope="module")
def crosstest() -> ExperimentSpec:
    return load_experiment_spec(EXAMPLE / "emps_crosstest.toml")


def _variant(spec: ExperimentSpec, loop: dict | None = None, **identify_keys) -> ExperimentSpec:
    table = spec.to_dict()
    table.pop("report", None)
    if loop is not None:
        table["loop"] = loop
        if "disturbance" not in loop:  # DATA_EMPS.mat lacks it: undeclared, not just unused
            table["channels"].pop("pulse_force")
    table["identify"] = {**table["identify"], "model": "symmetric", **identify_keys}
    return ExperimentSpec.from_dict(table, base_dir=spec.base_dir)


def test_the_pulses_as_disturbance_explain_the_validation_record(crosstest):
    with_pulses = identify(_variant(crosstest), write=False)
    loop = {k: v for k, v in crosstest.loop.items() if k != "disturbance"}
    blind = identify(_variant(crosstest, loop), write=False)
    key = "idim-ls symmetric"
    seen = with_pulses.validation["DATA_EMPS_PULSES.mat"][key]
    missed = blind.validation["DATA_EMPS_PULSES.mat"][key]
    # measured: force 6.35 % from rest with the pulses, 37 % without; position 0.0019 % vs
    # 0.062 %: the pulses are a large part of the record's force, and only the declared
    # disturbance lets the simulated loop carry them
    assert seen["force_from_rest"] < 7.0
    assert missed["force_from_rest"] > 30.0
    assert 10 * seen["position_from_rest"] < missed["position_from_rest"]
    # the inverse model needs no disturbance: the measured force contains the pulses
    assert seen["inverse"] == missed["inverse"]
    # DATA_EMPS.mat has no pulses_N: zero there, and the run says so
    assert any("DATA_EMPS.mat has no 'pulses_N'" in n for n in with_pulses.notes)
    assert with_pulses.to_dict()["loop_inputs"] == {
        "disturbance": "pulse_force", "disturbance_at": "drive", "reference_offset": 0.0}


def test_a_reference_offset_moves_the_simulated_axis(crosstest):
    loop = {**crosstest.loop, "reference_offset": 1e-3}
    shifted = identify(_variant(crosstest, loop), write=False)
    plain = identify(_variant(crosstest), write=False)
    key = "idim-ls symmetric"
    # a 1 mm offset on a 0.25 m stroke: the simulated axis follows r + 1 mm, far from qm
    assert shifted.loop_errors[key]["position"] > 100 * plain.loop_errors[key]["position"]


@pytest.mark.parametrize(
    ("loop", "error", "match"),
    [
        ({"disturbance": "pulses"}, DataError, r"\[loop\] disturbance = 'pulses' is not a channel"),
        ({"disturbance": 3}, OptionTypeError, r"\[loop\] disturbance must be a string"),
        ({"disturbance_at": "motor"}, OptionError, r"\[loop\] disturbance_at must be one of"),
        ({"reference_offset": "1 mm"}, OptionTypeError, r"\[loop\] reference_offset must be"),
        ({"disturbance_gain": 1.0}, OptionError, "unknown key.*disturbance_gain"),
    ],
)
def test_bad_loop_inputs_name_the_key(crosstest, loop, error, match):
    bad = _variant(crosstest, {**crosstest.loop, **loop})
    with pytest.raises(error, match=match):
        identify(bad, write=False)


def test_a_disturbance_missing_from_every_record_is_refused(crosstest):
    table = crosstest.to_dict()
    table.pop("report", None)
    table.pop("validation")
    table["identify"] = {**table["identify"], "model": "symmetric"}
    spec = ExperimentSpec.from_dict(table, base_dir=crosstest.base_dir)
    with pytest.raises(DataError, match="no record has that channel's source"):
        identify(spec, write=False)


def test_a_disturbance_in_volts_is_refused(crosstest):
    table = crosstest.to_dict()
    table.pop("report", None)
    table["channels"]["pulse_force"] = {**table["channels"]["pulse_force"], "unit": "V"}
    spec = ExperimentSpec.from_dict(table, base_dir=crosstest.base_dir)
    with pytest.raises(DataError, match="gain = gtau"):
        identify(spec, write=False)


def test_another_missing_channel_is_still_an_error(crosstest):
    table = crosstest.to_dict()
    table.pop("report", None)
    table["channels"]["qm"] = {**table["channels"]["qm"], "source": "q_motor"}
    spec = ExperimentSpec.from_dict(table, base_dir=crosstest.base_dir)
    with pytest.raises(ChannelError, match="q_motor"):
        identify(spec, write=False)


def test_closed_loop_oe_with_the_disturbance_recovers_the_axis():
    """Output error on a record made by the independent simulation, pulses at the drive."""
    r, d = _case(2000)
    q, f = _reference_loop(AXIS, CTRL, r, d, True, 0.0, r[0])
    exp = Experiment.from_arrays(DT, r=r, y=q, side={"force": f, "pulses": d})
    start = RigidAxis(105.0, 180.0, 22.0, -2.0)
    est = fit_closed_loop_oe(exp, CTRL, start, disturbance="pulses")
    # noise-free data from the same structure: the generator agrees with simulate_rigid_loop
    # to rounding (above) and LM stops at tol = 1e-10; measured 4e-14, 1e-8 bounds it
    np.testing.assert_allclose(est.parameters, [95.0, 200.0, 20.0, -3.0], rtol=1e-8)
    assert est.options["disturbance"] == "pulses"
    blind = fit_closed_loop_oe(exp, CTRL, start)
    # without the pulses the fit must explain 175 N steps by friction and mass: biased by
    # 3 % (M, Fv, Fc) to 58 % (offset), measured
    assert np.max(np.abs(blind.parameters / [95.0, 200.0, 20.0, -3.0] - 1)) > 0.01
