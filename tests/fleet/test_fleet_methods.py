"""A fleet row is the record's own summary: any method's scalars are trended, an FRF's too."""

from __future__ import annotations

import csv
import math
import warnings

import pytest

from servoid.fleet import run_fleet
from servoid.workflows import get_method, identify


@pytest.fixture(scope="module")
def frf_fleet(tmp_path_factory):
    """Four records identified with method = "frf" (no fitted model): spec numbers only."""
    folder = tmp_path_factory.mktemp("frf-fleet")
    example = get_method("frf").example
    paths = [example(folder / f"u{k}", k) for k in range(4)]
    with open(folder / "units.csv", "w", newline="", encoding="utf-8") as fh:
        writer = csv.writer(fh)
        writer.writerow(["path", "serial", "date"])
        writer.writerows([p.relative_to(folder), f"SN-{k}", f"2026-11-0{k + 1}"]
                         for k, p in enumerate(paths))
    (folder / "fleet.toml").write_text('[records]\nmanifest = "units.csv"\n\n[trend]\n'
                                       'by = "date"\n',
                                       encoding="utf-8")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = run_fleet(folder / "fleet.toml", workers=1, progress=False)
    return paths, result


def test_an_frf_fleet_trends_bandwidth_and_resonance(frf_fleet):
    paths, result = frf_fleet
    assert result.count("ok") == 4
    names = [p.name for p in result.parameters]
    assert names == ["bandwidth", "resonance_peak", "resonance_frequency"]
    assert [p.unit for p in result.parameters] == ["Hz", "dB", "Hz"]
    first = identify(paths[0], write=False)
    row = result.rows[0]
    assert row["bandwidth"] == first.numbers["bandwidth (-3 dB) [Hz]"]  # the record's own number
    assert math.isnan(row["bandwidth_std"])  # read from the measurement: no interval
    bandwidth = next(p for p in result.parameters if p.name == "bandwidth")
    assert bandwidth.n == 4 and bandwidth.drift is not None  # a trend over the dates
    html = (result.folder / "report.html").read_text(encoding="utf-8")
    assert "bandwidth [Hz]" in html and "resonance_peak [dB]" in html  # a section each


def test_the_table_has_a_column_per_spec_number(frf_fleet):
    _, result = frf_fleet
    with open(result.folder / "fleet.csv", encoding="utf-8") as fh:
        header = next(csv.reader(fh))
    for name in ("bandwidth", "resonance_peak", "resonance_frequency"):
        assert name in header and f"{name}_std" in header
    assert all(r["method"] == "frf" for r in result.rows)
