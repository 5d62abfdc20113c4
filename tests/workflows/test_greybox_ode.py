"""``method = "greybox"``: a user's ODE from the experiment file, through the API and the CLI.

The records come from the example's independent generator
(``examples/greybox/make_data.py``: numpy RK4 at 20 steps per sample, overflow
by projection, white sensor noise).
"""

from __future__ import annotations

import importlib.util
import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from servoid import ConvergenceError, MissingFileError, ModelError, OptionError, OptionTypeError
from servoid.cli import main
from servoid.workflows import get_method, identify

EXAMPLE = Path(__file__).parents[2] / "examples" / "greybox"
_spec = importlib.util.spec_from_file_location("greybox_example_data", EXAMPLE / "make_data.py")
GEN = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(GEN)

# the example's model, with a trace of its execution and some broken variants
MODEL = (EXAMPLE / "tanks.py").read_text(encoding="utf-8") + '''

from pathlib import Path as _Path

_Path(__file__).with_name("executed.txt").write_text("the model file ran")


def rhs_three(x, u, p):
    return (0.0, 0.0, 0.0)


def rhs_raises(x, u, p):
    raise ValueError("negative level")
'''

TOML = """
[data]
file = "est.csv"
time = "t"
time_unit = "s"

[channels]
pump = {{ role = "u", unit = "V" }}
level = {{ role = "y", unit = "m" }}

[validation]
file = "val.csv"

[identify]
method = "greybox"
model = "{model}"
output_function = "tanks.py:level"
states = ["h1", "h2"]
initial_state = [0.1, 0.1]
estimate_initial = {estimate_initial}
fixed = ["A"]
{extra}
[identify.parameters]
k = {k}
a1 = [2.0e-5, 1.0e-7, 1.0e-3]
a2 = [2.0e-5, 1.0e-7, 1.0e-3]
A = 0.0154

[identify.saturation]
{saturation}
"""


def _write(folder: Path, *, model: str = "tanks.py:rhs", k: str = "[2.0e-5, 1.0e-7, 1.0e-3]",
           estimate_initial: str = '["h1", "h2"]', extra: str = "",
           saturation: str = 'h1 = [0.0, 0.30]\npump = [0.0, 8.0]') -> Path:
    path = folder / "tanks.toml"
    path.write_text(TOML.format(model=model, k=k, estimate_initial=estimate_initial,
                                extra=extra, saturation=saturation), encoding="utf-8")
    return path


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    base = tmp_path_factory.mktemp("greybox")
    (base / "tanks.py").write_text(MODEL, encoding="utf-8")
    for name, seed, h0 in (("est.csv", 41, (0.12, 0.06)), ("val.csv", 42, (0.05, 0.15))):
        t, u, y, _ = GEN.record(900, seed, h0)
        GEN.write(base / name, t, u, y)
    return base


@pytest.fixture()
def case(folder, tmp_path):
    """A fresh folder holding the module's records and model file."""
    for name in ("tanks.py", "est.csv", "val.csv"):
        shutil.copy(folder / name, tmp_path / name)
    return tmp_path


def test_the_method_is_registered_with_its_keys():
    method = get_method("greybox")
    for key in ("model", "output_function", "states", "parameters", "initial_state",
                "estimate_initial", "saturation", "fixed", "multistart", "covariance",
                "substeps"):
        assert key in method.keys
    assert "--allow-code" in method.summary


def test_without_allow_code_the_file_is_refused_unread(case, capsys):
    toml = _write(case)
    code = main(["identify", str(toml), "--out", str(case / "out")])
    err = capsys.readouterr().err
    assert code != 0
    assert "--allow-code" in err and str((case / "tanks.py").resolve()) in err
    assert not (case / "executed.txt").exists()  # the model file never ran
    with pytest.raises(OptionError, match=r"\[identify\] model = \"tanks.py:rhs\" is Python "
                                          r"code .*allow_code=True"):
        identify(toml, write=False)
    assert not (case / "executed.txt").exists()


def test_with_allow_code_the_cli_fits_and_validates(case, capsys):
    toml = _write(case)
    code = main(["identify", str(toml), "--out", str(case / "out"), "--allow-code", "--json"])
    out, err = capsys.readouterr()
    assert code == 0, err
    assert (case / "executed.txt").exists()
    assert not (case / "__pycache__").exists()  # nothing written beside the user's file
    payload = json.loads(out)
    assert payload["method"] == "greybox"
    assert payload["model"]["type"] == "greybox_ode" and payload["model"]["compiled"] is True
    rows = {r["name"]: r for r in payload["estimate"]["parameters"]}
    assert set(rows) == {"k", "a1", "a2", "h1(0)", "h2(0)"}
    for name, true in (("k", GEN.TRUE["k"]), ("a1", GEN.TRUE["a1"]), ("a2", GEN.TRUE["a2"]),
                       ("h1(0)", 0.12), ("h2(0)", 0.06)):
        assert abs(rows[name]["value"] - true) < 4 * rows[name]["std"], name  # 4σ
    assert rows["k"]["unit"] == ""  # no [identify.units] here
    # the validation record starts elsewhere: its initial state is refitted, the fit is good
    assert payload["validation"]["fit_percent"] > 95.0
    results = json.loads((case / "out" / "results.json").read_text(encoding="utf-8"))
    assert results["model"]["parameters"]["A"] == 0.0154
    assert (case / "out" / "report.html").read_text(encoding="utf-8").count("grey-box ODE") >= 1


def test_the_python_integrator_gives_the_same_fit(case):
    def run(extra: str):  # one free parameter: the Python integrator is slow
        toml = _write(case, estimate_initial="[]", extra=extra)
        toml.write_text(toml.read_text(encoding="utf-8").replace(
            'fixed = ["A"]', 'fixed = ["A", "k", "a1"]'), encoding="utf-8")
        return identify(toml, write=False, allow_code=True)

    compiled, plain = run(""), run("compile = false\n")
    assert compiled.estimate.options["compiled"] and not plain.estimate.options["compiled"]
    assert "compile = false" in " ".join(plain.notes)
    assert plain.estimate.names == ("a2",)
    # one integrator source: the same numbers up to the solver's tolerance
    np.testing.assert_allclose(plain.estimate.parameters, compiled.estimate.parameters,
                               rtol=1e-6)


@pytest.mark.parametrize("edit, error, match", [
    ({"model": "tanks.py:nosuch"}, OptionError,
     r"tanks.py has no function 'nosuch'; it defines level, rhs, rhs_raises, rhs_three"),
    ({"model": "missing.py:rhs"}, MissingFileError, r"model = \"missing.py:rhs\": no file"),
    ({"model": "tanks.py"}, OptionError, r"must name a Python file and a function"),
    ({"model": "tanks.txt:rhs"}, OptionError, r"must be a Python file"),
    ({"model": "tanks.py:rhs_three"}, ModelError, r"shape \(3,\) for 2 states"),
    ({"model": "tanks.py:rhs_raises"}, ModelError,
     r"tanks.py, line \d+, in rhs_raises: raise ValueError.*ValueError: negative level"),
    ({"k": "[2.0e-5, 1.0e-3, 1.0e-7]"}, OptionError,
     r"\[identify.parameters\] k: lower = 0.001 must be below upper = 1e-07"),
    ({"k": "[2.0, 1.0e-7, 1.0e-3]"}, OptionError, r"k: the start value 2 lies outside"),
    ({"k": "[2.0e-5, 1.0]"}, OptionError, r"give the start value, or \[start, lower, upper\]"),
    ({"k": '"fast"'}, OptionTypeError, r"\[identify.parameters\] k must be a number"),
    ({"estimate_initial": '["h3"]'}, OptionError,
     r"estimate_initial names 'h3', which is not a state; the states are h1, h2"),
    ({"saturation": "h9 = [0.0, 1.0]"}, OptionError,
     (r"\[identify.saturation\] h9: not a state or an input channel; the states are h1, h2 "
     r"and the inputs pump")),
    ({"saturation": "h1 = [0.3, 0.0]"}, OptionError, r"h1 = \[0.3, 0\]: lower must be below"),
    ({"extra": "substeps = 0\n"}, Exception, r"\[identify\] substeps must be >= 1"),
    ({"extra": 'log = ["k"]\n', "k": "[2.0e-5, -1.0, 1.0e-3]"}, OptionError,
     (r"\[identify\] log names 'k': fitted as log k, it needs a start > 0 and a lower bound >= 0, "
     r"got start 2e-05, lower -1")),
    ({"extra": 'log = ["B"]\n'}, OptionError, r"\[identify\] log names 'B', not in"),
    ({"extra": "max_nfev = 1\n"}, ConvergenceError, r"did not converge.*raise max_nfev"),
])
def test_bad_inputs_give_clear_errors(case, edit, error, match):
    toml = _write(case, **edit)
    with pytest.raises(error, match=match):
        identify(toml, write=False, allow_code=True)


def test_unknown_fixed_parameter_and_initial_state_length(case):
    toml = _write(case)
    text = toml.read_text(encoding="utf-8")
    toml.write_text(text.replace('fixed = ["A"]', 'fixed = ["B"]'), encoding="utf-8")
    with pytest.raises(OptionError, match=r"\[identify\] fixed names 'B', not in "
                                          r"\[identify.parameters\]"):
        identify(toml, write=False, allow_code=True)
    toml.write_text(text.replace("initial_state = [0.1, 0.1]", "initial_state = [0.1]"),
                    encoding="utf-8")
    with pytest.raises(OptionError, match=r"initial_state has 1 values and states names 2"):
        identify(toml, write=False, allow_code=True)


def test_a_syntax_error_in_the_model_file_names_its_line(case):
    (case / "broken.py").write_text("def rhs(x, u, p):\n    return (x[0]\n", encoding="utf-8")
    with pytest.raises(ModelError, match=r"broken.py, line \d+"):
        identify(_write(case, model="broken.py:rhs"), write=False, allow_code=True)


def test_the_example_runs(tmp_path, capsys):
    for path in EXAMPLE.iterdir():
        if path.suffix in (".py", ".toml", ".csv"):
            shutil.copy(path, tmp_path / path.name)
    code = main(["identify", str(tmp_path / "tanks.toml"), "--allow-code", "--json"])
    out, err = capsys.readouterr()
    assert code == 0, err
    payload = json.loads(out)
    rows = {r["name"]: r for r in payload["estimate"]["parameters"]}
    for name in ("k", "a1", "a2"):
        assert abs(rows[name]["value"] - GEN.TRUE[name]) < 4 * rows[name]["std"], name  # 4σ
    assert rows["k"]["unit"] == "m³/(s·V)"
    assert (tmp_path / "tanks-results" / "report.html").is_file()
