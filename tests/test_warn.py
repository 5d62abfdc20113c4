"""servoid's warnings name the caller's line, whatever the depth inside servoid."""

from __future__ import annotations

import json
import re
import sys
import types
import warnings
from pathlib import Path

import numpy as np
import pytest

import servoid
from servoid import ServoidWarning
from servoid.signals import multisine, prbs
from servoid.validate import relative_error, vaf

SRC = Path(servoid.__file__).parent


def _caught(call):  # type: ignore[no-untyped-def]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        call()
    return [w for w in caught if issubclass(w.category, ServoidWarning)]


@pytest.mark.parametrize("call", [
    lambda: relative_error(np.zeros(8), np.ones(8)),  # warns in the public function itself
    lambda: vaf(np.ones(8), np.arange(8.0)),  # in a private helper it calls
    lambda: multisine(1000, 1e-3, 2.0, 2.5),  # only one line in the band
], ids=["relative_error", "vaf", "multisine"])
def test_a_public_function_warns_at_the_callers_line(call):
    caught = _caught(call)
    assert caught
    for w in caught:
        assert w.filename == __file__, (w.filename, str(w.message))


def test_a_closed_loop_fit_warns_at_the_callers_line(tmp_path):
    """fit_one_step → fit_tf_greybox → the identifiability checks: three servoid frames deep."""
    from servoid.data import load_experiment_spec
    from servoid.plants.ehsa import (
        SET_C,
        EhsaBench,
        FeedbackLoop,
        fit_one_step,
        run,
        write_bench_files,
    )

    # Set C at 1 kHz: its resonance is out of reach, K and ω_hp are not separately identifiable
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ServoidWarning)  # the bench says so too
        record = run(EhsaBench(params=SET_C, snr_db=30.0),
                     prbs(10, clock=10, amplitude=1e-3, dt=1e-3), rng=3)
    files = write_bench_files(record, tmp_path)
    data, _ = load_experiment_spec(files[1]).split_data()
    line = sys._getframe().f_lineno + 1
    caught = _caught(lambda: fit_one_step(data, FeedbackLoop(0.01, 0.01),
                                          discretization="prewarp"))
    assert any("not separately identifiable" in str(w.message) for w in caught)
    assert {(w.filename, w.lineno) for w in caught} == {(__file__, line)}


def test_writing_results_warns_at_the_callers_line(tmp_path):
    from servoid.data import Experiment, write_csv, write_experiment_spec
    from servoid.workflows import identify, write_results

    rng = np.random.default_rng(1)
    u = rng.standard_normal(600)
    y = np.convolve(u, [0.0, 0.5, 0.25])[:600] + 0.01 * rng.standard_normal(600)
    write_csv(Experiment.from_arrays(0.01, u=u, y=y), tmp_path / "run.csv")
    write_experiment_spec({"data": {"file": "run.csv", "time": "time", "time_unit": "s"},
                           "channels": {"u": {"role": "u"}, "y": {"role": "y"}},
                           "identify": {"method": "arx", "na": 1, "nb": 2, "nk": 1}},
                          tmp_path / "run.toml")
    result = identify(tmp_path / "run.toml", write=False)
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "results.json").write_text("{}", encoding="utf-8")
    lock = {"servoid_lock": 1, "pid": 999999, "token": "0123456789abcdef", "folders": ["."],
            "files": ["results.json"]}  # a run killed half way: its lock, no process holds it
    (tmp_path / "out" / ".servoid.lock").write_text(json.dumps(lock), encoding="utf-8")
    line = sys._getframe().f_lineno + 1
    caught = _caught(lambda: write_results(result, tmp_path / "out"))
    assert [(w.filename, w.lineno) for w in caught if "interrupted" in str(w.message)] == \
        [(__file__, line)]


def test_through_another_library_the_outermost_servoid_call_is_named():
    """servoid → a solver (not servoid) → servoid → warn: the user's line, not the solver's."""
    from servoid._warn import warn

    solver = types.ModuleType("a_solver")  # stands for scipy calling a residual function back
    exec("def minimise(fn):\n    return fn()\n", solver.__dict__)  # noqa: S102
    inner = {"__name__": "servoid._fake_residual", "warn": warn}
    exec("def residual():\n    warn('the residual is flat')\n", inner)  # noqa: S102
    outer = {"__name__": "servoid._fake_fit", "solver": solver, "residual": inner["residual"]}
    exec("def fit():\n    return solver.minimise(residual)\n", outer)  # noqa: S102
    line = sys._getframe().f_lineno + 1
    caught = _caught(lambda: outer["fit"]())
    assert [(w.filename, w.lineno) for w in caught] == [(__file__, line)]


def test_every_warning_in_the_package_goes_through_the_helper():
    calls = [f"{path.relative_to(SRC)}:{n}" for path in sorted(SRC.rglob("*.py"))
             if path.name != "_warn.py"
             for n, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1)
             if re.search(r"\bwarnings\.warn\(", line)]
    assert calls == [], "use servoid._warn.warn, which names the caller's line: " + \
        ", ".join(calls)
