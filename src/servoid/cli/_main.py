"""The ``servoid`` command: a thin shell over the public API.

Exit codes: 0 success, 1 a servoid or file error (the message says what
and how to fix it), 2 a usage error (from the argument parser), 130
interrupted (Ctrl-C; a fleet writes the table of the records done first). With
``--json`` every failure, a usage error too, prints ``{"ok": false, ...}``.
"""

from __future__ import annotations

import argparse
import json
import sys
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Any, NoReturn

from .. import __version__
from .._errors import ServoidError, ServoidWarning
from .._words import command_line_words
from ._flags import out_path

__all__ = ["main"]


def main(argv: Sequence[str] | None = None) -> int:
    """Run the ``servoid`` command; return the exit code."""
    parser = _parser()
    words = list(sys.argv[1:] if argv is None else argv)
    try:
        args = parser.parse_args(words)
    except _UsageError as usage:
        usage.parser.print_usage(sys.stderr)
        print(f"{usage.parser.prog}: error: {usage.message}", file=sys.stderr)
        if "--json" in words:
            print(json.dumps({"ok": False, "error": usage.message, "type": "UsageError"}))
        return 2
    except SystemExit as stop:  # argparse exits on --help/--version (0)
        return int(stop.code or 0)
    from .._progress import configure, watch_compiles
    from ..workflows._provenance import set_command

    set_command(["servoid", *words])
    shown = (sys.stderr.isatty() and not getattr(args, "json", False)
             and not getattr(args, "quiet", False))
    configure(shown)
    if shown and args.run.__name__ not in _LIGHT:  # these compute: say when numba compiles
        watch_compiles()
    try:
        with warnings.catch_warnings(record=True) as caught, command_line_words():
            warnings.simplefilter("always", ServoidWarning)
            payload, text = args.run(args)
    except KeyboardInterrupt:
        print("servoid: interrupted", file=sys.stderr)
        return 130
    except (ServoidError, OSError) as exc:
        message = str(exc) or type(exc).__name__
        if getattr(args, "json", False):
            print(json.dumps({"ok": False, "error": message, "type": type(exc).__name__}))
        print(f"servoid: error: {message}", file=sys.stderr)
        return 1
    said = _warnings(caught)
    if getattr(args, "json", False):
        from ..report import to_jsonable

        print(json.dumps({"ok": True, **to_jsonable(payload), "warnings": said}, indent=2))
    else:
        print(text)
    for message in said:  # a result's notes already print them; say the others once
        if message not in text:
            print(f"servoid: warning: {message}", file=sys.stderr)
    return 0


def _warnings(caught: list[warnings.WarningMessage]) -> list[str]:
    messages = [str(w.message) for w in caught if issubclass(w.category, ServoidWarning)]
    for w in caught:  # a library's warning: its words, without Python source lines
        if not issubclass(w.category, ServoidWarning):
            print(f"servoid: warning ({w.category.__name__}): {w.message}", file=sys.stderr)
    return list(dict.fromkeys(messages))


class _UsageError(Exception):
    """A usage error of the argument parser, kept for the ``--json`` answer."""

    def __init__(self, parser: argparse.ArgumentParser, message: str) -> None:
        super().__init__(message)
        self.parser = parser
        self.message = message


class _Parser(argparse.ArgumentParser):
    """argparse's parser, raising its usage errors instead of exiting (sub-parsers too)."""

    def error(self, message: str) -> NoReturn:
        raise _UsageError(self, message)


#: Commands that never reach a compiled kernel (no need to import numba for them).
_LIGHT = frozenset({"_run_methods", "_run_export", "_run_prbs", "_run_multisine", "_run_chirp"})


def _parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="servoid",
        description="Identify servo actuators from test-bench data.",
        epilog="Run 'servoid COMMAND --help' for the options of a command.",
    )
    parser.add_argument("--version", action="version", version=f"servoid {__version__}")
    commands = parser.add_subparsers(title="commands", metavar="COMMAND", required=True)

    demo = commands.add_parser(
        "demo", help="run the demo end to end",
        description="Design a PRBS, rehearse the test on a servo with known dynamics, write the "
        "rig file and experiment TOML, identify, validate, and print truth vs estimate.",
    )
    demo.add_argument("--out", type=out_path, default="servoid-demo", help="folder for the demo's files "
                      "(default: %(default)s; an earlier demo's files there are replaced)")
    demo.add_argument("--seed", type=int, default=2026, help="noise seed (default: %(default)s)")
    demo.add_argument("--overwrite", action="store_true",
                      help="write into a non-empty folder that holds no earlier demo")
    _json_flag(demo)
    demo.set_defaults(run=_run_demo)

    identify = commands.add_parser(
        "identify", help="identify a model from an experiment file",
        description="Load the rig file an experiment TOML names, preprocess and split it, fit "
        "the model of its [identify] table, validate on the held-back part or the [validation] "
        "records, and write results.json, figures and report.html. 'servoid methods' lists "
        "the methods and their [identify] keys.",
    )
    identify.add_argument("experiment", type=Path, help="experiment file (.toml)")
    identify.add_argument("--out", type=out_path, help="results folder (default: [report] folder, "
                          "else <experiment>-results beside the TOML)")
    identify.add_argument("--overwrite", action="store_true",
                          help="replace results of an earlier run (inputs are never overwritten)")
    identify.add_argument("--allow-outside", action="store_true",
                          help="let [report] folder point outside the experiment file's folder")
    identify.add_argument("--allow-code", action="store_true",
                          help="let the experiment file's Python model file run (method = "
                          "\"greybox\"); check the file first")
    identify.add_argument("--max-bytes", type=int, default=None,
                          help="refuse a rig file (data or validation record) larger than this "
                          "many bytes before reading it (default: no limit on the file; a "
                          ".mat variable keeps the reader's 2 GiB budget)")
    _json_flag(identify)
    identify.set_defaults(run=_run_identify)

    methods = commands.add_parser(
        "methods", help="list the identification methods and their [identify] keys",
        description="Without a name: every method [identify] method = ... can name, with one "
        "line each. With a name: that method's [identify] keys, defaults and the other tables "
        "it reads.",
    )
    methods.add_argument("name", nargs="?", help="a method name, e.g. oe")
    _json_flag(methods)
    methods.set_defaults(run=_run_methods)

    from ._bench import add_bench
    from ._excite import add_excite
    from ._export import add_export
    from ._fleet import add_fleet

    add_excite(commands, _json_flag)
    add_bench(commands, _json_flag)
    add_fleet(commands, _json_flag)
    add_export(commands, _json_flag)
    return parser


def _json_flag(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--json", action="store_true", help="print machine-readable JSON")


def _run_demo(args: argparse.Namespace) -> tuple[dict[str, Any], str]:
    from ..workflows import run_demo
    from ._flags import at_least, folder_out

    at_least("--seed", args.seed, 0)
    folder_out("--out", Path(args.out))
    result = run_demo(args.out, seed=args.seed, overwrite=args.overwrite)
    return result.to_dict(), str(result)


def _run_methods(args: argparse.Namespace) -> tuple[dict[str, Any], str]:
    from ..workflows import get_method, method_names

    if args.name:
        method = get_method(args.name)
        return method.to_dict(), method.describe()
    listed = [get_method(n) for n in method_names()]
    width = max(len(m.name) for m in listed)
    text = "\n".join(f"{m.name:<{width}}  {m.summary}" for m in listed)
    text += "\n\n'servoid methods NAME' shows a method's [identify] keys."
    return {"methods": [m.to_dict() for m in listed]}, text


def _run_identify(args: argparse.Namespace) -> tuple[dict[str, Any], str]:
    from ..workflows import identify
    from ._flags import at_least

    if args.max_bytes is not None:
        at_least("--max-bytes", args.max_bytes, 1)
    result = identify(args.experiment, args.out, overwrite=args.overwrite,
                      allow_outside=args.allow_outside, max_bytes=args.max_bytes,
                      allow_code=args.allow_code)
    return result.to_dict() | {"files": [str(f) for f in result.files]}, str(result)
