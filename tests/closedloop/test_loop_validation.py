"""An unstable identified plant is validated in its loop; [loop] open silences the feedback test."""

from __future__ import annotations

import dataclasses
import sys
import warnings
from pathlib import Path
from types import MappingProxyType

import pytest

sys.path.insert(0, str(Path(__file__).parent))

from anyloop_rigs import RIGS

from servoid import OptionTypeError, ServoidWarning
from servoid.data import load_experiment_spec, write_csv, write_experiment_spec
from servoid.workflows import identify
from servoid.workflows._examples import closed_loop


@pytest.fixture(scope="module")
def unstable(tmp_path_factory):
    folder = tmp_path_factory.mktemp("unstable")
    rig = RIGS["unstable"]
    for k, seed in enumerate((1, 2)):
        write_csv(rig.closed(seed, 4000).experiment(), folder / f"loop{k}.csv")
    return folder


def _run(folder, method, orders, loop=None):
    table = {"data": {"file": "loop0.csv"},
             "channels": {"r": {"role": "r"}, "u": {"role": "u"}, "y": {"role": "y"}},
             "validation": {"file": "loop1.csv"}, "identify": {"method": method, **orders}}
    if loop:
        table["loop"] = loop
    path = folder / f"{method}.toml"
    write_experiment_spec(table, path, overwrite=True)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ServoidWarning)
        return identify(path, write=False)


@pytest.mark.parametrize(("method", "orders", "known"), [
    ("cliv", {"na": 3, "nb": 3}, False),
    ("indirect", {"nb": 3, "nf": 3}, True),
])
def test_an_unstable_plant_is_validated_in_its_loop(unstable, method, orders, known):
    cn, cd = RIGS["unstable"].controller
    loop = {"controller": {"num": [float(x) for x in cn], "den": [float(x) for x in cd]}}
    result = _run(unstable, method, orders, loop if known else None)
    note = next(n for n in result.notes if "validated in its loop" in n)
    assert "the identified plant is unstable (a pole at |z| = 1.0" in note
    assert ("the known controller of [loop]" if known else "the controller identified from "
            "the record") in note
    verdict = result.verdict()
    assert "simulated in its loop from the reference" in verdict.tested
    # a free run of this plant grows without bound; in its loop the fit is a number in words
    assert 60 < result.validation.fit_percent < 100, result.validation.fit_percent
    assert verdict.decision != "reject", verdict.lines()


def test_two_stage_on_an_unstable_plant_says_so_in_its_verdict(unstable):
    result = _run(unstable, "two-stage", {"nb": 3, "nf": 3})
    check = next(c for c in result.verdict().checks if c.name == "consistency")
    assert check.outcome == "caution"
    assert "the plant is unstable" in check.meaning and "cliv" in check.meaning


def test_loop_open_silences_the_feedback_test(tmp_path):
    spec = load_experiment_spec(closed_loop(tmp_path, 0, identify={"method": "oe"}))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ServoidWarning)
        said = identify(spec, write=False)
        quiet = identify(dataclasses.replace(spec, loop=MappingProxyType({"open": True})),
                         write=False)
    assert said.feedback is not None and said.feedback.has_feedback
    assert any("looks closed loop" in n for n in said.notes)
    assert quiet.feedback is None
    assert not any("looks closed loop" in n for n in quiet.notes)


def test_loop_open_must_be_a_boolean(tmp_path):
    spec = load_experiment_spec(closed_loop(tmp_path, 0, identify={"method": "oe"}))
    with pytest.raises(OptionTypeError, match=r"\[loop\] open must be true or false"):
        identify(dataclasses.replace(spec, loop=MappingProxyType({"open": "yes"})),
                 write=False)
