"""Every command's --help reads as written: no argparse escapes left in the text."""

from __future__ import annotations

import argparse

import pytest

from servoid.cli._main import _parser


def _parsers(parser: argparse.ArgumentParser, prog: str = "servoid"):
    yield prog, parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield from _parsers(sub, f"{prog} {name}")


def test_no_help_prints_a_doubled_percent_sign():
    # '%%' is argparse's escape in an argument's help, but a description prints it as is
    pages = dict(_parsers(_parser()))
    assert {"servoid fleet", "servoid bench fleet", "servoid identify"} <= set(pages)
    doubled = [prog for prog, parser in pages.items() if "%%" in parser.format_help()]
    assert doubled == []
    text = " ".join(pages["servoid bench fleet"].format_help().split())
    assert "leakage 8 %" in text and "+50 %" in text


def test_the_command_line_says_flags_and_the_api_says_arguments(tmp_path, capsys):
    from servoid import OutputExistsError
    from servoid.cli import main
    from servoid.data import write_csv
    from servoid.signals import prbs

    target = tmp_path / "prbs.csv"
    target.write_text("taken\n")
    argv = ["excite", "prbs", "-n", "5", "--dt", "0.01", "--out", str(target)]
    assert main(argv) == 1
    err = capsys.readouterr().err
    assert "--overwrite" in err and "overwrite=True" not in err
    with pytest.raises(OutputExistsError) as api:
        write_csv(prbs(5, dt=0.01).to_experiment(), target)
    assert "overwrite=True" in str(api.value) and "--overwrite" not in str(api.value)
