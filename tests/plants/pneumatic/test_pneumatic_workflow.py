"""Servopneumatic campaign (method = "pneumatic-multistep") → results.json and report."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from servoid import DataError, OptionError
from servoid.data import Experiment, load_experiment_spec, write_experiment_spec, write_tdms
from servoid.plants.pneumatic import (
    PNEUMATIC_NOMINAL,
    KnownConstants,
    PneumaticIdentification,
    PositionController,
    simulate_pneumatic,
)
from servoid.workflows import identify

TRUTH = PNEUMATIC_NOMINAL
DT = 1e-4
CHANNELS = ("u", "x_ref", "x_k", "x_v", "p_I", "p_II", "T_I", "T_II", "mdot_I", "mdot_II",
            "v_k", "a_k", "f_ext")
ROLES = {"u": "u", "x_ref": "r", "x_k": "y"}


def to_record(res, name):
    """The bench's channels (SI) from a simulator response; ṁ clipped at 4 g/s."""
    side = {"x_v": res.x_v, "p_I": res.p_I, "p_II": res.p_II, "T_I": res.T_I,
            "T_II": res.T_II, "mdot_I": np.clip(res.m_dot_I, -4e-3, 4e-3),
            "mdot_II": np.clip(res.m_dot_II, -4e-3, 4e-3), "v_k": res.x_k_dot,
            "a_k": res.x_k_ddot, "f_ext": res.f_ext}
    units = {"u": "V", "x_ref": "m", "x_k": "m", "x_v": "m", "p_I": "Pa", "p_II": "Pa",
             "T_I": "K", "T_II": "K", "mdot_I": "kg/s", "mdot_II": "kg/s", "v_k": "m/s",
             "a_k": "m/s²", "f_ext": "N"}
    kw = {"u": res.u, "y": res.x_k, "side": side, "units": units,
          "names": {"u": "u", "y": "x_k", "r": "x_ref"}}
    if res.r is not None:
        kw["r"] = res.r
    return Experiment.from_arrays(res.dt, name=name, **kw)


def valve_response(duration):
    t = np.arange(round(duration / 5e-5)) * 5e-5
    return simulate_pneumatic(TRUTH, np.where(np.sin(2 * np.pi * 25 * t + 1e-9) >= 0, 5.0, -5.0),
                              5e-5)


def sine_response(duration, amplitude=0.02, freq=1.0, force=0.0):
    t = np.arange(round(duration / DT)) * DT
    f_ext = None if force == 0.0 else np.where(np.sin(2 * np.pi * 0.75 * t) >= 0, force, -force)
    return simulate_pneumatic(TRUTH, None, DT, r=amplitude * np.sin(2 * np.pi * freq * t),
                              controller=PositionController(), f_ext=f_ext)


def write_test(folder, name, exp):
    write_tdms(exp, folder / f"{name}.tdms")
    channels = {c: {"role": ROLES.get(c, "side"), "unit": exp.unit(c)}
                for c in CHANNELS if c in exp.names}
    table = {"data": {"file": f"{name}.tdms", "group": "servoid"}, "channels": channels}
    write_experiment_spec(table, folder / f"{name}.toml")
    return table


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    folder = tmp_path_factory.mktemp("pneumatic")
    sine = to_record(sine_response(duration=1.5), "flow")
    records = {"valve": to_record(valve_response(0.2), "valve"),
               "thermo": to_record(sine_response(duration=1.5, force=60.0), "thermo"),
               "flow": sine, "friction": sine,
               "validation": to_record(sine_response(duration=1.0, amplitude=0.05, freq=2.0),
                                       "validation")}
    tables = {name: write_test(folder, name, exp) for name, exp in records.items()}
    truth = {f.name: getattr(TRUTH, f.name) for f in dataclasses.fields(TRUTH)}
    (folder / "truth.json").write_text(json.dumps({"parameters": truth}))
    return folder, tables


def write_campaign(folder, tables, identify=None, loop=None):
    known = KnownConstants.from_parameters(TRUTH).to_dict()
    table = dict(tables["validation"])
    table["identify"] = identify or {
        "method": "pneumatic-multistep", "valve": "valve.toml", "thermo": "thermo.toml",
        "flow": "flow.toml", "friction": "friction.toml", "validation": "validation.toml",
        "known": known, "derivatives": "measured", "refine": ["c_k"]}
    table["loop"] = loop if loop is not None else {"K_p": 300.0, "K_d": 5.0}
    table["report"] = {"truth": "truth.json"}
    path = folder / "pneumatic.toml"
    write_experiment_spec(table, path, overwrite=True)
    return load_experiment_spec(path)


def test_campaign_writes_results_and_report(campaign, tmp_path):
    folder, tables = campaign
    spec = write_campaign(folder, tables)
    out = identify(spec, tmp_path / "out")
    assert isinstance(out, PneumaticIdentification)
    assert {p.name for p in out.files} >= {"results.json", "report.html", "validation.png",
                                           "steps.png", "validation_refined.png"}
    data = json.loads((tmp_path / "out" / "results.json").read_text())
    rows = {r["name"]: r for r in data["parameters"]}
    assert abs(rows["F_haft"]["error_percent"]) < 1e-6  # noise-free, measured derivatives
    assert rows["kappa"]["truth"] == 1.4
    assert data["validation"]["fit_percent"]["p_I"] > 99
    html = (tmp_path / "out" / "report.html").read_text()
    for title in ("S0 p_krit", "S1: servovalve", "S2: thermodynamic", "S3: flow", "S4:", "S5:",
                  "S6: validation"):
        assert title in html
    assert "error vs truth" in str(out)
    # the verdict judges the S6 fits the page shows, multi-step and refined, record by record
    verdict = out.verdict()
    fits = {c.name: c.value for c in verdict.checks if c.name.startswith("S6 fit")}
    assert fits["S6 fit p_I"] == f"{data['validation']['fit_percent']['p_I']:.1f} %"
    assert "S6 fit x_k (refined)" in fits and verdict.decision == "accept"
    assert "not computed by this method" not in html and "ACCEPT — passes every check" in html
    assert [c.record.split(":")[0] for c in verdict.conditions] == [
        "valve", "thermo", "flow", "friction", "validation"]
    assert data["verdict"]["decision"] == "accept"
    assert "Grey-box refinement" in html and out.result.refinement is not None
    # starts at the truth; moves only to absorb the other estimates' ~1e-7 errors
    assert abs(out.result.refinement.parameters.c_k / 120.0 - 1) < 1e-4
    with pytest.raises(FileExistsError):
        identify(spec, tmp_path / "out")
    identify(spec, tmp_path / "out", overwrite=True)


def test_known_in_loop_and_validation_from_data(campaign):
    folder, tables = campaign
    known = KnownConstants.from_parameters(TRUTH).to_dict()
    spec = write_campaign(folder, tables,
                          identify={"method": "pneumatic-multistep", "valve": "valve.toml",
                                    "thermo": "thermo.toml", "flow": "flow.toml",
                                    "friction": "friction.toml", "derivatives": "measured"},
                          loop=known)  # no gains: the controller is reconstructed
    out = identify(spec, write=False)
    assert out.files == () and out.folder is None
    assert out.result.validation.notes  # "controller reconstructed ..."
    assert out.result.validation.fit["p_II"] > 99


def test_campaign_errors(campaign):
    folder, tables = campaign
    bad = {"method": "pneumatic-multistep", "valve": "valve.toml", "colour": "red"}
    with pytest.raises(OptionError, match="colour"):
        identify(write_campaign(folder, tables, identify=bad), write=False)
    lacking = {"method": "pneumatic-multistep", "valve": "valve.toml", "thermo": "thermo.toml",
               "flow": "flow.toml"}
    with pytest.raises(DataError, match="friction"):
        identify(write_campaign(folder, tables, identify=lacking), write=False)
    no_known = {"method": "pneumatic-multistep", "valve": "valve.toml", "thermo": "thermo.toml",
                "flow": "flow.toml", "friction": "friction.toml"}
    with pytest.raises(DataError, match="known constants lack"):
        identify(write_campaign(folder, tables, identify=no_known, loop={}), write=False)
