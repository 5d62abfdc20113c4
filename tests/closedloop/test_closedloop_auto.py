"""method = "closedloop-auto": the loop's facts pick the methods; estimates side by side."""

from __future__ import annotations

import json
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent))

from anyloop_rigs import RIGS

from servoid import ServoidWarning
from servoid.data import Experiment, write_csv, write_experiment_spec
from servoid.workflows import identify


def _run(folder, rig, *, loop=None, reference=True, out=None):
    for k, seed in enumerate((1, 2)):
        rec = rig.closed(seed, 4000)
        exp = rec.experiment() if reference else Experiment.from_arrays(rig.dt, u=rec.u,
                                                                        y=rec.y)
        write_csv(exp, folder / f"loop{k}.csv")
    channels = {"u": {"role": "u"}, "y": {"role": "y"}}
    if reference:
        channels["r"] = {"role": "r"}
    nb, nf, nk = rig.orders
    table = {"data": {"file": "loop0.csv"}, "channels": channels,
             "validation": {"file": "loop1.csv"},
             "identify": {"method": "closedloop-auto", "nb": nb, "nf": nf, "nk": nk}}
    if loop:
        table["loop"] = loop
    write_experiment_spec(table, folder / "e.toml", overwrite=True)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ServoidWarning)
        return identify(folder / "e.toml", out, write=out is not None)


def _rows(result):
    return {row["method"]: row for row in result.estimate.options["candidates"]}


def test_a_known_controller_picks_the_indirect_approach(tmp_path):
    rig = RIGS["unstable"]
    cn, cd = rig.controller
    loop = {"controller": {"num": [float(x) for x in cn], "den": [float(x) for x in cd]}}
    result = _run(tmp_path, rig, loop=loop, out=tmp_path / "out")
    rows = _rows(result)
    assert result.estimate.options["chosen"] == "indirect"
    assert list(rows) == ["indirect", "direct-bj", "cliv", "two-stage"]
    # every method that claims consistency holds the truth within 4σ (one record)
    truth = dict(zip(["b0", "b1", "b2", "f1", "f2", "f3"], rig.theta(), strict=True))
    for name in ("indirect", "direct-bj"):
        row = rows[name]
        assert row["claims_consistency"]
        for key, value in truth.items():
            assert abs(row["parameters"][key] - value) < 4 * row["std"][key], (name, key)
    # the two-stage method says why it is not consistent on an unstable plant
    assert not rows["two-stage"]["claims_consistency"]
    assert "the plant is unstable" in rows["two-stage"]["broken_assumptions"][0]
    assert any(n.startswith("side by side: two-stage (not consistent here") for n in
               result.notes)
    saved = json.loads((tmp_path / "out" / "results.json").read_text(encoding="utf-8"))
    assert [r["method"] for r in saved["closedloop_candidates"]] == list(rows)
    assert any("validated in its loop" in n for n in result.notes)


def test_without_a_reference_only_the_direct_approach_runs(tmp_path):
    result = _run(tmp_path, RIGS["delay"], reference=False)
    rows = _rows(result)
    assert result.estimate.options["chosen"] == "direct-bj"
    assert rows["cliv"]["why"] == "skipped: the record has no reference r"
    assert rows["indirect"]["why"].startswith("skipped: the controller is not known")
    assert "parameters" not in rows["two-stage"]


def test_an_unknown_controller_prefers_the_direct_approach(tmp_path):
    rig = RIGS["delay"]
    result = _run(tmp_path, rig)
    rows = _rows(result)
    assert result.estimate.options["chosen"] == "direct-bj"
    assert all(rows[m]["claims_consistency"] for m in ("direct-bj", "cliv", "two-stage"))
    # the estimates agree: each within 4σ of the direct one (b0 of the sampled plant)
    b0 = rows["direct-bj"]["parameters"]["b0"]
    for m in ("cliv", "two-stage"):
        assert abs(rows[m]["parameters"]["b0"] - b0) < 4 * rows[m]["std"]["b0"], m
    assert np.isfinite(result.validation.fit_percent)


@pytest.mark.parametrize("bad", [{"nb": 0}, {"nc": -1}])
def test_bad_orders_are_refused(tmp_path, bad):
    from servoid import DataError

    rig = RIGS["delay"]
    write_csv(rig.closed(1, 2000).experiment(), tmp_path / "l.csv")
    write_experiment_spec({"data": {"file": "l.csv"},
                           "channels": {"r": {"role": "r"}, "u": {"role": "u"},
                                        "y": {"role": "y"}},
                           "identify": {"method": "closedloop-auto", **bad}},
                          tmp_path / "e.toml")
    with pytest.raises(DataError, match=r"\[identify\] n[bc] must be >= [01]"):
        identify(tmp_path / "e.toml", write=False)
