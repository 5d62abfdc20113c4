"""The command line is never silent for long, and its warnings come before its results.

On a pipe (CI, ``| tee``) every command writes plain stage lines to stderr.
The tests give stderr a real file (a descriptor, as a pipe has) and replace
the progress thread with one look "10 s later" each time a stage opens, so
that every stage shows as it starts: what is checked is which lines a
command writes, not how fast — no test waits on a timer.
"""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap

import numpy as np
import pytest

import servoid._progress as progress
from servoid.cli import main
from servoid.data import Experiment, write_csv, write_experiment_spec
from servoid.models import PolynomialModel


class _Pipe:
    """stderr as a file (a descriptor, as a pipe has), while the test runs a command."""

    def __init__(self, path) -> None:  # type: ignore[no-untyped-def]
        self.path = path
        self.log = open(path, "w+", encoding="utf-8")  # noqa: SIM115

    def __enter__(self) -> _Pipe:
        # set in the test's body: pytest puts its capture in place of stderr before each phase
        self.saved, sys.stderr = sys.stderr, self.log
        return self

    def __exit__(self, *exc: object) -> None:
        sys.stderr = self.saved

    def text(self) -> str:
        self.log.flush()
        return self.path.read_text(encoding="utf-8")


@pytest.fixture
def stderr_pipe(tmp_path, monkeypatch):
    """A file to put in place of stderr; each stage shown as soon as it opens."""
    monkeypatch.setattr(progress, "_start_ticker",
                        lambda: progress._tick(progress._now() + 10.0))
    pipe = _Pipe(tmp_path / "stderr.txt")
    yield pipe
    pipe.log.close()


def _stages(text: str) -> list[str]:
    assert "\r" not in text and "\x1b" not in text  # plain lines, no redrawn terminal line
    return [line for line in text.splitlines() if line.startswith("servoid: ")]


@pytest.fixture
def arx_rig(tmp_path):
    """A small ARX record (as tests/workflows/test_identify.py) and its experiment file."""
    truth = PolynomialModel.arx([1.0, -1.2, 0.5], [0.8, 0.3], 1, 0.01)
    rng = np.random.default_rng(7)
    u = rng.standard_normal(2000)
    y = truth.simulate(u) + 0.01 * rng.standard_normal(2000)
    exp = Experiment.from_arrays(0.01, u=u, y=y, names={"u": "cmd", "y": "pos"})
    write_csv(exp, tmp_path / "run.csv")
    path = tmp_path / "run.toml"
    write_experiment_spec({"data": {"file": "run.csv", "time": "time", "time_unit": "s"},
                           "channels": {"cmd": {"role": "u"}, "pos": {"role": "y"}},
                           "identify": {"method": "arx", "na": 2, "nb": 2, "nk": 1}}, path)
    return path


def test_identify_on_a_pipe_names_each_stage(arx_rig, stderr_pipe, capsys):
    with stderr_pipe:
        assert main(["identify", str(arx_rig)]) == 0
    lines = _stages(stderr_pipe.text())
    assert lines[0] == "servoid: identify … 0:10"  # from the start: the imports are covered
    assert "servoid: identifying (arx) … 0:10" in lines
    assert "servoid: writing the figures and the report … 0:10" in lines
    assert "ARX" in capsys.readouterr().out


def test_methods_names_its_stage_and_lists_without_loading_a_method(stderr_pipe, capsys):
    with stderr_pipe:
        assert main(["methods"]) == 0
    assert _stages(stderr_pipe.text()) == ["servoid: methods … 0:10"]
    assert "greybox" in capsys.readouterr().out
    code = textwrap.dedent("""
        import sys
        from servoid.cli import main
        main(["methods"])
        print(sorted(m for m in sys.modules if m.startswith("servoid.workflows._")
                     or m in ("matplotlib", "scipy.optimize", "numba")), file=sys.stderr)
    """)
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=120, check=True)
    loaded = eval(done.stderr.strip().splitlines()[-1])  # noqa: S307 — a list this test printed
    assert loaded == ["servoid.workflows._methods", "servoid.workflows._registry"]


def test_bench_and_fleet_name_their_stages(tmp_path, stderr_pipe, capsys):
    out = tmp_path / "fleet"
    with stderr_pipe:
        assert main(["bench", "fleet", "--out", str(out), "--units", "3", "--corrupt", "0",
                     "--register", "5"]) == 0
    lines = stderr_pipe.text().splitlines()
    assert lines[0] == "servoid: bench fleet … 0:10"
    assert any(line.startswith("simulating units 3/3") for line in lines)  # its batch bar
    mark = len(stderr_pipe.text())
    with stderr_pipe:
        assert main(["fleet", str(out / "fleet.toml"), "--workers", "1"]) == 0
    lines = stderr_pipe.text()[mark:].splitlines()
    assert lines[0] == "servoid: fleet … 0:10"
    assert any(line.startswith("identifying 3/3") for line in lines)
    mark = len(stderr_pipe.text())
    with stderr_pipe:
        assert main(["bench", "ehsa", "--register", "7", "--out", str(tmp_path / "ehsa")]) == 0
    assert _stages(stderr_pipe.text()[mark:])[:2] == [
        "servoid: bench ehsa … 0:10",
        "servoid: simulating the reduced EHSA bench (1270 samples at 1000 Hz) … 0:10"]
    capsys.readouterr()


def test_json_and_an_in_memory_stderr_stay_silent(arx_rig, capsys):
    assert main(["methods"]) == 0  # capsys: stderr is a buffer, not a pipe
    assert capsys.readouterr().err == ""


def _merged(*argv: str, cwd) -> list[str]:  # type: ignore[no-untyped-def]
    """stdout and stderr of ``python -m servoid`` in one pipe, in the order they came."""
    done = subprocess.run([sys.executable, "-m", "servoid", *argv], stdout=subprocess.PIPE,
                          stderr=subprocess.STDOUT, text=True, timeout=300, cwd=cwd,
                          check=True)
    return done.stdout.splitlines()


def test_a_warning_comes_before_the_results(tmp_path):
    lines = _merged("excite", "multisine", "--period", "1000", "--dt", "0.001", "--f-min", "2",
                    "--f-max", "2.5", "--out", "ms.csv", cwd=tmp_path)
    warned = next(i for i, line in enumerate(lines) if line.startswith("servoid: warning: only"))
    result = next(i for i, line in enumerate(lines) if line.startswith("multisine: 1000 samples"))
    assert warned < result, lines


_NOISY = """
import logging, sys, warnings
import servoid.cli._main as cli

def noisy(args):
    warnings.warn("overflow encountered in exp", RuntimeWarning)
    logging.getLogger("numba.core.ssa").warning("a third party's log line")
    return {{}}, "done"

cli._run_methods = noisy
sys.exit(cli.main({argv!r}))
"""


@pytest.mark.parametrize("verbose", [False, True], ids=["quiet", "-v"])
def test_other_libraries_are_quiet_unless_verbose(tmp_path, verbose):
    argv = ["methods", "-v"] if verbose else ["methods"]
    done = subprocess.run([sys.executable, "-c", _NOISY.format(argv=argv)], capture_output=True,
                          text=True, timeout=120, check=True)
    assert done.stdout == "done\n"
    if verbose:
        assert "servoid: log (numba.core.ssa, WARNING): a third party's log line" in done.stderr
        assert "servoid: warning (RuntimeWarning, <string>:6): overflow encountered in exp" \
            in done.stderr
    else:
        assert "log line" not in done.stderr and "overflow" not in done.stderr
        assert "servoid: 1 warning from other libraries (RuntimeWarning) not shown; -v shows " \
            "them" in done.stderr


def test_verbose_goes_before_or_after_the_command(capsys):
    assert main(["-v", "methods", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["ok"] is True
    assert main(["methods", "--json", "--verbose"]) == 0
    assert json.loads(capsys.readouterr().out)["ok"] is True
