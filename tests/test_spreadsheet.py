"""CSV cells a spreadsheet would run as formulas: neutralised in tables, refused in rig files."""

from __future__ import annotations

import numpy as np
import pytest

from servoid import DataError, Experiment
from servoid._spreadsheet import neutralise
from servoid.data import read_csv, write_csv


@pytest.mark.parametrize(
    ("cell", "written"),
    [("=1+1", "'=1+1"), ("+49 30 1234", "'+49 30 1234"), ("+1-2", "'+1-2"),
     ("-2+3+cmd|' /C calc'!A0", "'-2+3+cmd|' /C calc'!A0"), ("@SUM(A1:A9)", "'@SUM(A1:A9)"),
     ("\t=1", "'\t=1"), ("\r=1", "'\r=1"), ("-inf", "'-inf"),
     ("-0.25", "-0.25"), ("+3e-5", "+3e-5"), ("-.5E+2", "-.5E+2"), ("SN-1", "SN-1"), ("", "")],
)
def test_neutralise(cell, written):
    assert neutralise(cell) == written


@pytest.mark.parametrize("name", ["=HYPERLINK(\"x\")", "@y", "+y", "-y"])
def test_rig_csv_refuses_a_formula_header(tmp_path, name):
    """A rig file must read back as written, so a formula header is refused, not altered."""
    exp = Experiment.from_arrays(0.1, u=np.zeros(4), y=np.ones(4), names={"y": name})
    with pytest.raises(DataError, match="a spreadsheet runs as a formula; rename the channel"):
        write_csv(exp, tmp_path / "rig.csv")
    assert not (tmp_path / "rig.csv").exists()
    exp = Experiment.from_arrays(0.1, u=np.zeros(4), y=np.ones(4), names={"y": "y-1"})
    assert read_csv(write_csv(exp, tmp_path / "ok.csv"), dt=0.1).names[-1] == "y-1"
