"""The method registry: options declared once, used by identify, the CLI and the docs."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.signal import lfilter

from servoid import DataError, OptionError, OptionTypeError
from servoid.cli import main
from servoid.data import Experiment, write_csv, write_experiment_spec
from servoid.models import PolynomialModel
from servoid.workflows import Method, Option, get_method, identify, method_names

TRUTH = PolynomialModel.arx([1.0, -1.2, 0.5], [0.8, 0.3], 1, 0.01)


def test_every_method_documents_its_options():
    assert {"arx", "closedloop", "inverse-dynamics", "pneumatic-multistep"} <= set(method_names())
    for name in method_names():
        method = get_method(name)
        assert method.summary and method.keys[0] == "method"
        for option in method.options:
            assert option.help, f"{name}.{option.name} has no help"
        text = method.describe()
        assert all(o.name in text for o in method.options)
        json.dumps(method.to_dict())  # plain data


def test_parse_fills_defaults_and_checks_values():
    arx = get_method("arx")
    assert arx.parse({"method": "arx"})["na"] == 2
    assert arx.parse({"na": [1, 2]})["na"] == [1, 2]
    with pytest.raises(OptionError, match='valid keys for method = "arx" are method, input'):
        arx.parse({"orders": 3})
    with pytest.raises(OptionTypeError, match=r"\[identify\] na must be an integer or a list"):
        arx.parse({"na": "two"})
    with pytest.raises(DataError, match=r"\[identify\] nb\[1\] must be >= 1"):
        arx.parse({"nb": [2, 0]})
    with pytest.raises(OptionError, match="criterion must be one of 'aic'"):
        arx.parse({"criterion": "bic?"})


def test_a_method_is_data():
    def run(spec, options, truth):
        raise AssertionError("not called")

    m = Method("demo-method", "a test", (Option("k", 1, lambda v, w, n: v, "k"),), run)
    assert m.keys == ("method", "k") and m.parse({"k": 3}) == {"k": 3}
    with pytest.raises(ValueError, match="unique"):
        Method("bad", "x", (Option("k", 1, lambda v, w, n: v, "k"),) * 2, run)


@pytest.fixture
def two_records(tmp_path):
    for k, seed in enumerate((7, 8)):
        rng = np.random.default_rng(seed)
        u = rng.standard_normal(3000)
        y = TRUTH.simulate(u) + lfilter([1.0], TRUTH.a, 0.02 * rng.standard_normal(3000))
        write_csv(Experiment.from_arrays(0.01, u=u, y=y + 3.0), tmp_path / f"run{k}.csv")
    return tmp_path


def _toml(folder, identify=None, **extra):
    table = {"data": {"file": "run0.csv"},
             "channels": {"cmd": {"source": "u", "role": "u", "unit": "V"},
                          "pos": {"source": "y", "role": "y", "unit": "mm"}},
             "preprocess": {"detrend": "mean"},
             "identify": {"method": "arx", **(identify or {})}, **extra}
    path = folder / "e.toml"
    write_experiment_spec(table, path, overwrite=True)
    return path


def test_separate_validation_record_and_order_table(two_records):
    path = _toml(two_records, {"na": [1, 2, 3, 4], "nb": [1, 2, 3], "criterion": "mdl"},
                 validation={"file": "run1.csv"})
    result = identify(path, write=False)
    assert result.estimate.options["na"] == 2 and result.estimate.options["nb"] == [2]
    assert result.validation.experiment == "run1" and result.validation.fit_percent > 95
    assert result.estimate.n_samples > 2900  # the whole first record is estimation data
    assert len(result.orders) == 12 and result.orders[0].orders == {"na": 2, "nb": 2, "nk": 1}
    text = str(result)
    assert "order search by mdl (12 candidates" in text and "validation on" in text


def test_order_on_the_edge_of_the_grid_is_a_note(two_records):
    path = _toml(two_records, {"na": [1], "nb": [1, 2], "criterion": "mdl"})
    with pytest.warns(UserWarning, match="edge of the searched grid"):
        result = identify(path, write=False)
    assert any("edge" in n for n in result.notes)


def test_validation_table_is_refused_where_it_would_be_ignored(two_records):
    path = _toml(two_records, {"method": "pneumatic-multistep"}, validation={"file": "run1.csv"})
    with pytest.raises(OptionError, match=r"\[validation\] table, which method = "
                                          r"\"pneumatic-multistep\" does not use"):
        identify(path, write=False)


def test_cli_methods(capsys):
    assert main(["methods"]) == 0
    out = capsys.readouterr().out
    assert all(name in out for name in method_names())
    assert main(["methods", "arx", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["ok"] and data["name"] == "arx"
    assert main(["methods", "nonsense"]) == 1
    assert "must be one of 'arx'" in capsys.readouterr().err


def test_results_written_with_report(two_records):
    path = _toml(two_records, {"na": 2, "nb": 2}, validation={"file": "run1.csv"})
    result = identify(path)
    names = {p.name for p in result.files}
    assert {"results.json", "report.html", "bode.png", "poles.png", "validation.png"} <= names
    data = json.loads((result.folder / "results.json").read_text())
    assert data["method"] == "arx" and data["validation_files"][0]["path"].endswith("run1.csv")
    html = (result.folder / "report.html").read_text()
    assert "Validation: run1" in html and "±2σ" in html
