"""A controller known only in continuous time: the indirect approach says when the guess matters.

The rigs of ``anyloop_rigs`` run a digital controller; here the unstable
plant's PD (filtered derivative, τ = 20 ms at 100 Hz: its pole is at 0.16
of the Nyquist frequency) ran as the zero-order-hold discretisation of its
design, while the indirect approach is given the continuous design and
discretises it by Tustin.  The motor's PI (its zero at 8 Hz, Nyquist
500 Hz) is the case where the guess cannot matter.
"""

from __future__ import annotations

import dataclasses
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
from scipy import signal

sys.path.insert(0, str(Path(__file__).parent))

from anyloop_rigs import RIGS

from servoid import DataError, ServoidWarning
from servoid.closedloop import fit_indirect_tf
from servoid.data import Experiment, write_csv, write_experiment_spec
from servoid.models import TransferFunction
from servoid.workflows import identify

#: the unstable rig's PD design, kp + kd·s/(τ s + 1), and the motor rig's PI, kp (1 + 1/(Ti s))
PD = TransferFunction([12.0 * 0.02 + 0.5, 12.0], [0.02, 1.0])
PI = TransferFunction([1.0 * 0.02, 1.0], [0.02, 0.0])


def _ran_as_zoh(name: str, design: TransferFunction):  # type: ignore[no-untyped-def]
    rig = RIGS[name]
    b, a, _ = signal.cont2discrete((design.num, design.den), rig.dt, method="zoh")
    b = np.atleast_1d(np.squeeze(b))
    return dataclasses.replace(rig, controller=(b / a[0], a / a[0]), _cache={})


def test_a_continuous_controller_near_nyquist_is_not_claimed():
    rig = _ran_as_zoh("unstable", PD)
    rec = rig.closed(0, 10_000)
    # r and y only: the indirect approach needs no u, and without u there is no IV point to
    # compare with, so this check is the only one that can see the controller's error
    exp = Experiment.from_arrays(rig.dt, r=rec.r, y=rec.y)
    with pytest.warns(ServoidWarning, match="given in continuous time"):
        est = fit_indirect_tf(exp, PD, 3, 3, 1)
    z = (est.parameters - rig.theta()) / est.std
    assert np.max(np.abs(z)) > 4.0  # the Tustin guess biases the plant: it would fail 4σ
    assert est.options["consistent"] is False
    assert len(est.options["broken_assumptions"]) == 1
    why = est.options["broken_assumptions"][0]
    assert "discretised at the record's dt = 0.01 s by tustin" in why
    assert "Nyquist frequency (50 Hz)" in why and "the zoh one differs" in why
    assert 'method = "cliv" or "two-stage"' in why
    assert est.options["discretisation"] == "tustin"


def test_a_slow_continuous_controller_is_claimed():
    rig = _ran_as_zoh("motor", PI)
    exp = rig.closed(0, 10_000, clock=2).experiment()
    with warnings.catch_warnings():
        warnings.simplefilter("error", ServoidWarning)
        est = fit_indirect_tf(exp, PI, 3, 3, 1)
    assert est.options["consistent"] is True
    z = (est.parameters - rig.theta()) / est.std
    assert np.all(np.abs(z) < 4.0), z  # 4σ: the Tustin guess costs nothing this far below π/dt


def _spec(folder: Path, rig, controller: dict) -> Path:  # type: ignore[no-untyped-def]
    for k, seed in enumerate((1, 2)):
        write_csv(rig.closed(seed, 4000, clock=2).experiment(), folder / f"loop{k}.csv")
    table = {"data": {"file": "loop0.csv"},
             "channels": {"r": {"role": "r"}, "u": {"role": "u"}, "y": {"role": "y"}},
             "validation": {"file": "loop1.csv"},
             "identify": {"method": "indirect", "nb": 3, "nf": 3, "nk": 1},
             "loop": {"controller": controller}}
    write_experiment_spec(table, folder / "e.toml", overwrite=True)
    return folder / "e.toml"


def test_loop_controller_can_be_given_in_continuous_time(tmp_path):
    path = _spec(tmp_path, _ran_as_zoh("motor", PI),
                 {"num": [0.02, 1.0], "den": [0.02, 0.0], "continuous": True})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ServoidWarning)
        result = identify(path, None, write=False)
    assert result.estimate.options["discretisation"] == "tustin"


def test_loop_controller_with_dt_and_continuous_is_refused(tmp_path):
    path = _spec(tmp_path, RIGS["motor"],
                 {"num": [1.0], "den": [1.0, 0.0], "continuous": True, "dt": 0.001})
    with pytest.raises(DataError, match="both dt and continuous = true"):
        identify(path, None, write=False)
