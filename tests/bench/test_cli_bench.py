"""``servoid bench ehsa`` in process, through a parser built with add_bench."""

from __future__ import annotations

import argparse
import json

import pytest

from servoid import DataError, OptionError, OutputExistsError
from servoid._words import command_line_words
from servoid.cli._bench import add_bench
from servoid.data import load_experiment_spec


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="servoid")
    commands = parser.add_subparsers(required=True)
    add_bench(commands, lambda p: p.add_argument("--json", action="store_true",
                                                 help="print machine-readable JSON"))
    return parser


def _call(*argv: str) -> tuple[dict, str]:
    args = _parser().parse_args(["bench", "ehsa", *argv])
    with command_line_words():  # as servoid.cli.main runs a command
        return args.run(args)


def test_writes_files_and_reports(tmp_path):
    payload, text = _call("-n", "7", "--format", "csv", "--seed", "4", "--out", str(tmp_path))
    assert [p.rsplit("/", 1)[-1] for p in payload["files"]] == [
        "ehsa.csv", "ehsa.toml", "truth.json"]
    assert payload["n_samples"] == 1270 and payload["n_samples_acq"] == 6350
    assert payload["band_hz"][1] == pytest.approx(44.5, abs=0.1)
    assert payload["truth"]["exact"] is True
    assert payload["truth"]["omega_hp"] == pytest.approx(163.3, rel=1e-3)
    json.dumps(payload)  # plain data for --json
    for word in ("1270 samples at 1000 Hz", "excited band", "omega_hp = 163.299", "written:"):
        assert word in text
    exp = load_experiment_spec(tmp_path / "ehsa.toml").load()
    assert exp.n_samples == 1270
    truth = json.loads((tmp_path / "truth.json").read_text(encoding="utf-8"))
    assert truth["seed"] == 4 and truth["snr_db"] == 30.0


def test_set_c_nonlinear_and_overwrite(tmp_path):
    argv = ("--set", "C", "--fidelity", "nonlinear", "-n", "6", "--periods", "2",
            "--snr", "40", "--bits", "14", "--out", str(tmp_path))
    payload, text = _call(*argv)
    assert payload["fidelity"] == "nonlinear" and payload["set"] == "C"
    assert payload["truth"]["exact"] is False
    assert "reduced-model values; data from the nonlinear model" in text
    assert load_experiment_spec(tmp_path / "ehsa.toml").split.period == 630
    with pytest.raises(OutputExistsError, match="--overwrite"):
        _call(*argv)
    _call(*argv, "--overwrite")


@pytest.mark.parametrize(
    ("argv", "error", "match"),
    [
        (("--clock", "0"), DataError, "cannot be faster than the sample rate"),
        (("--facq", "4500"), DataError, "integer multiple of f_s"),
        (("--fidelity", "linear"), OptionError, "'reduced', 'full', 'nonlinear'"),
        (("--snr", "nan"), DataError, "--snr must be a finite"),
        (("--bits", "30"), DataError, "bits must lie in 8..24"),
        (("--amplitude", "0.03"), DataError, "lower the amplitude"),
    ],
)
def test_bad_input(tmp_path, argv, error, match):
    with pytest.raises(error, match=match):
        _call(*argv, "--out", str(tmp_path))
    assert not any(tmp_path.iterdir())


def test_help_on_every_option():
    parser = _parser()
    sub = next(a for a in parser._subparsers._group_actions)
    ehsa = sub.choices["bench"]._subparsers._group_actions[0].choices["ehsa"]
    for action in ehsa._actions:
        assert action.help, action.dest
