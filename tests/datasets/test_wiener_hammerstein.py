"""The shipped Wiener–Hammerstein benchmark parts: the benchmark's split, checked bytes."""

from __future__ import annotations

import shutil

import numpy as np
import pytest

from servoid import FileFormatError, OptionError
from servoid.datasets import WH_PARTS, load_wiener_hammerstein, wiener_hammerstein_path
from servoid.datasets import _wiener_hammerstein as wh


@pytest.mark.parametrize(("part", "n", "first", "last"), [
    # rows 5200 and 105199, 105200 and 183999 of WienerHammerBenchmark.csv (u, y)
    ("estimation", 100_000, (-0.034678, -0.11124), None),
    ("test", 78_800, None, (-1.1584, -0.070385)),
])
def test_parts_are_the_benchmark_split(part, n, first, last):
    exp = load_wiener_hammerstein(part)
    assert exp.n_samples == n and exp.dt == 1 / 51200 and exp.names == ("u", "y")
    assert exp.unit("u") == exp.unit("y") == "V"
    if first is not None:
        assert (exp["u"][0], exp["y"][0]) == first  # the CSV's text, parsed exactly
    if last is not None:
        assert (exp["u"][-1], exp["y"][-1]) == last
    assert "SYSID 2009" in exp.notes["citation"]


def test_a_changed_file_is_refused(tmp_path, monkeypatch):
    from scipy.io import loadmat, savemat

    m = loadmat(wiener_hammerstein_path("test"))
    m["y"][10] += 1e-6
    copy = tmp_path / "wh_test.mat"
    savemat(copy, {"u": m["u"], "y": m["y"]}, do_compression=True)
    monkeypatch.setattr(wh, "wiener_hammerstein_path", lambda part: copy)
    with pytest.raises(FileFormatError, match="sha256"):
        load_wiener_hammerstein("test")
    shutil.copy(wiener_hammerstein_path("test"), copy)  # the shipped bytes load
    assert load_wiener_hammerstein("test").n_samples == 78_800


def test_an_unknown_part_names_the_shipped_ones():
    with pytest.raises(OptionError, match="estimation"):
        load_wiener_hammerstein("validation")
    assert WH_PARTS == ("estimation", "test")
    assert np.isfinite(load_wiener_hammerstein()["y"]).all()
