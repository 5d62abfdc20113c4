"""A grey-box model numba cannot compile: said before the fit, with the reason and the time.

The Python integrator may need many minutes; the warning comes before the
fit starts (the fit is replaced here by a stand-in that stops the run), with
the time one simulation of the record takes — timed on a few steps and
extrapolated — and the range the fit needs.
"""

from __future__ import annotations

import importlib.util
import re
import warnings
from pathlib import Path

import numpy as np
import pytest

import servoid.workflows._greybox as greybox
from servoid import ServoidWarning
from servoid.estimate._ode import make_system, simulation_seconds
from servoid.workflows import identify

EXAMPLE = Path(__file__).parents[2] / "examples" / "greybox"
_spec = importlib.util.spec_from_file_location("greybox_fallback_data", EXAMPLE / "make_data.py")
GEN = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(GEN)

# the example's model, made uncompilable by a Python object numba cannot type
UNCOMPILABLE = (EXAMPLE / "tanks.py").read_text(encoding="utf-8") + '''

class _Scratch:
    pass


def rhs_object(x, u, p):
    _Scratch()
    return rhs(x, u, p)
'''


class _Stop(Exception):
    pass


@pytest.fixture
def case(tmp_path):
    (tmp_path / "tanks.py").write_text(UNCOMPILABLE, encoding="utf-8")
    t, u, y, _ = GEN.record(400, 41, (0.12, 0.06))
    GEN.write(tmp_path / "tanks.csv", t, u, y)
    toml = (EXAMPLE / "tanks.toml").read_text(encoding="utf-8")
    toml = toml.replace('model = "tanks.py:rhs"', 'model = "tanks.py:rhs_object"')
    toml = re.sub(r"(?m)^\[validation\]\nfile = .*\n", "", toml)
    (tmp_path / "tanks.toml").write_text(toml, encoding="utf-8")
    return tmp_path


def test_the_fall_back_is_announced_before_the_fit(case, monkeypatch):
    caught: list[warnings.WarningMessage]  # bound by catch_warnings below
    labels: list[str] = []

    def fit_ode(*args, **kwargs):  # stands for the slow fit: what was said before it?
        said = [str(w.message) for w in caught if issubclass(w.category, ServoidWarning)]
        raise _Stop(said)

    real_stage = greybox.stage

    def stage(label):  # type: ignore[no-untyped-def]
        labels.append(label)
        return real_stage(label)

    monkeypatch.setattr(greybox, "fit_ode", fit_ode)
    monkeypatch.setattr(greybox, "stage", stage)
    # one simulation of the record: 0.5 s (the timing itself is checked below)
    monkeypatch.setattr(greybox, "simulation_seconds", lambda *a, **k: 0.5)
    with warnings.catch_warnings(record=True) as caught, pytest.raises(_Stop) as stopped:
        warnings.simplefilter("always")
        identify(case / "tanks.toml", write=False, allow_code=True)
    said = stopped.value.args[0]
    assert len(said) == 1, said
    # k, a1, a2 and two initial states free: 6 simulations an iteration, 5–20 iterations,
    # 5 starts (multistart = 4): 150–600 simulations of 0.5 s
    # numba's reason in one line, naming the user's line (not "Failed in nopython mode …")
    assert said[0].startswith("tanks.py:rhs_object does not compile with numba (Untyped global "
                              "name '_Scratch': Cannot determine Numba type of <class 'type'>; "
                              "tanks.py, line 36); ")
    assert said[0].endswith(  # the estimation half of the 400 samples (no [validation] file)
        "the Python integrator runs (much slower): one simulation of the 200 samples takes "
        "0.5 s and the fit needs some 150–600 of them (5 free parameters, 5 starts), so expect "
        "75 s to 5 min; a model numba compiles fits about 100 times faster "
        "(docs/greybox-ode.md says what compiles)")
    assert labels == ["fitting with the Python integrator (expect 75 s to 5 min)"]


def test_compile_false_is_a_choice_not_a_warning(case, monkeypatch):
    toml = case / "tanks.toml"
    toml.write_text(toml.read_text(encoding="utf-8").replace(
        'model = "tanks.py:rhs_object"', 'model = "tanks.py:rhs"\ncompile = false'),
        encoding="utf-8")
    monkeypatch.setattr(greybox, "fit_ode", lambda *a, **k: (_ for _ in ()).throw(_Stop()))
    with warnings.catch_warnings(record=True) as caught, pytest.raises(_Stop):
        warnings.simplefilter("always")
        identify(toml, write=False, allow_code=True)
    assert not [w for w in caught if issubclass(w.category, ServoidWarning)]


def test_the_time_of_a_simulation_is_extrapolated_from_a_few_steps(case):
    tanks = importlib.util.spec_from_file_location("fallback_tanks", case / "tanks.py")
    module = importlib.util.module_from_spec(tanks)
    tanks.loader.exec_module(module)
    u = np.ones((100_000, 1))
    system = make_system(module.rhs, module.level, x0=np.array([0.1, 0.1]), u=u,
                         p=np.array([1.5e-5, 2.5e-5, 2.5e-5, 0.0154]),
                         state_lower=np.zeros(2), state_upper=np.full(2, np.inf),
                         input_lower=np.zeros(1), input_upper=np.full(1, 8.0),
                         source="tanks.py:rhs", compile=False)
    steps = []
    real = system.simulate

    def counted(x0, u_part, *args):  # type: ignore[no-untyped-def]
        steps.append(u_part.shape[0])
        return real(x0, u_part, *args)

    object.__setattr__(system, "simulate", counted)
    seconds = simulation_seconds(system, np.array([0.1, 0.1]), u,
                                 np.array([1.5e-5, 2.5e-5, 2.5e-5, 0.0154]), 1.0, 1)
    assert steps[0] == 16 and all(b == 4 * a for a, b in zip(steps, steps[1:], strict=False))
    assert steps[-1] < u.shape[0]  # a part of the record, not all of it
    assert seconds > 0.0
