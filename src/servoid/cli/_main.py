"""The ``servoid`` command: a thin shell over the public API.

Progress goes to stderr — a redrawn line on a terminal, plain lines on a
pipe or in a file — so that no command is silent for more than about 2 s;
servoid's warnings come as they happen, and any not shown yet come before
the results, not after them.  Other libraries' logging and warnings stay
quiet unless ``-v``/``--verbose`` is given.

Exit codes: 0 success, 1 a servoid or file error (the message says what
and how to fix it), 2 a usage error (from the argument parser), 130
interrupted (Ctrl-C; a fleet writes the table of the records done first). With
``--json`` every failure, a usage error too, prints ``{"ok": false, ...}``.
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import sys
import warnings
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any, NoReturn

from .._errors import ServoidError, ServoidWarning
from .._flags import out_path
from .._version import __version__
from .._words import command_line_words

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
    from .._progress import configure, live_stream, take_notices

    as_json, verbose = getattr(args, "json", False), getattr(args, "verbose", False)
    # progress on a terminal, a pipe or a file (CI, | tee); not into an in-memory buffer
    shown = not as_json and not getattr(args, "quiet", False) and live_stream(sys.stderr)
    configure(shown, sys.stderr, verbose=verbose)
    said: list[str] = []  # servoid's warnings, in order, once each
    others: list[warnings.WarningMessage] = []  # other libraries' warnings
    try:
        try:
            with command_line_words():  # messages name --flags, not keyword=values
                payload, text = _run(args, words, _command(parser, words), shown, said, others)
        finally:  # the warnings not shown yet, then the output goes back to silent
            pending = take_notices() if shown else [f"servoid: warning: {m}" for m in said]
            configure(False)
    except KeyboardInterrupt:
        _pending(pending, "")
        print("servoid: interrupted", file=sys.stderr)
        return 130
    except (ServoidError, OSError) as exc:
        message = str(exc) or type(exc).__name__
        if as_json:
            print(json.dumps({"ok": False, "error": message, "type": type(exc).__name__}))
        print(f"servoid: error: {message}", file=sys.stderr)
        _pending(pending, "")  # the error first, then what was said on the way (it may explain)
        return 1
    # before the results, not after them: a warning may change what they mean
    _pending(pending, text)
    _libraries(others, verbose)
    if as_json:
        from ..report import to_jsonable

        text = json.dumps({"ok": True, **to_jsonable(payload), "warnings": said}, indent=2)
    try:
        print(text, flush=True)
    except BrokenPipeError:  # the reader stopped (| head): no traceback, and none at exit
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
    return 0


def _run(args: argparse.Namespace, words: list[str], command: list[str], shown: bool,
         said: list[str], others: list[warnings.WarningMessage]) -> tuple[dict[str, Any], str]:
    """Run the command in a stage of its name, its warnings shown as they come."""
    from .._progress import notice, stage, watch_compiles

    def show(message: Warning | str, category: type[Warning], filename: str, lineno: int,
             file: Any = None, line: str | None = None) -> None:
        if issubclass(category, ServoidWarning):
            if str(message) not in said:
                said.append(str(message))
                notice(f"servoid: warning: {message}")  # shown while the run goes on
        else:
            others.append(warnings.WarningMessage(message, category, filename, lineno))

    with _library_logging(getattr(args, "verbose", False)), warnings.catch_warnings():
        warnings.simplefilter("always", ServoidWarning)
        warnings.showwarning = show
        with stage(" ".join(command)):  # from here on, nothing is silent for long
            if command != ["methods"]:  # a report names the command that wrote it
                from ..workflows import set_command

                set_command(["servoid", *words])
            if shown and args.run.__name__ not in _LIGHT:  # these compute: name numba's compiles
                watch_compiles()
            return args.run(args)  # type: ignore[no-any-return]


def _pending(lines: list[str], text: str) -> None:
    """Print the warnings not shown yet, except those the results' notes already give."""
    for line in lines:
        message = line.removeprefix("servoid: warning: ")
        if not (text and message in text):
            print(f"servoid: warning: {message}", file=sys.stderr)


def _libraries(caught: list[warnings.WarningMessage], verbose: bool) -> None:
    """Other libraries' warnings: each with -v, else one line that counts them."""
    if verbose:
        for w in caught:  # their words and where, without Python source lines
            print(f"servoid: warning ({w.category.__name__}, {Path(w.filename).name}:{w.lineno}): "
                  f"{w.message}", file=sys.stderr)
    elif caught:
        kinds = ", ".join(sorted({w.category.__name__ for w in caught}))
        print(f"servoid: {len(caught)} warning{'s' * (len(caught) > 1)} from other libraries "
              f"({kinds}) not shown; -v shows them", file=sys.stderr)


@contextmanager
def _library_logging(verbose: bool) -> Iterator[None]:
    """Other libraries' logging (numba, matplotlib, …): silent, or with -v shown from INFO up."""
    root = logging.getLogger()
    level = root.level
    if verbose:
        handler: logging.Handler = logging.StreamHandler(sys.stderr)
        handler.setFormatter(logging.Formatter("servoid: log (%(name)s, %(levelname)s): "
                                               "%(message)s"))
        root.setLevel(logging.INFO)
    else:  # a handler on the root: records no library handles go nowhere, not to stderr
        handler = logging.NullHandler()
    root.addHandler(handler)
    try:
        yield
    finally:
        root.removeHandler(handler)
        root.setLevel(level)


def _command(parser: argparse.ArgumentParser, words: Sequence[str]) -> list[str]:
    """The command's words (``bench fleet``), without its options and arguments."""
    names: list[str] = []
    for word in words:
        sub = next((a for a in parser._actions if isinstance(a, argparse._SubParsersAction)),
                   None)
        if sub is None:
            break
        if word in sub.choices:
            names.append(word)
            parser = sub.choices[word]
    return names


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
    parser.add_argument("-v", "--verbose", action="store_true", help=_VERBOSE)
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
    _add_verbose(parser)
    return parser


_VERBOSE = "show other libraries' logging and warnings (numba, Dask, matplotlib)"


def _add_verbose(parser: argparse.ArgumentParser) -> None:
    """``-v`` after the command too (``servoid identify x.toml -v``), on every leaf command."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub in dict.fromkeys(action.choices.values()):
                if any(isinstance(a, argparse._SubParsersAction) for a in sub._actions):
                    _add_verbose(sub)
                else:
                    sub.add_argument("-v", "--verbose", action="store_true",
                                     default=argparse.SUPPRESS, help=_VERBOSE)


def _json_flag(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--json", action="store_true", help="print machine-readable JSON")


def _run_demo(args: argparse.Namespace) -> tuple[dict[str, Any], str]:
    from .._flags import at_least, folder_out
    from ..plants.ehsa import run_demo

    at_least("--seed", args.seed, 0)
    folder_out("--out", Path(args.out))
    result = run_demo(args.out, seed=args.seed, overwrite=args.overwrite)
    return result.to_dict(), str(result)


def _run_methods(args: argparse.Namespace) -> tuple[dict[str, Any], str]:
    from ..workflows import METHODS, get_method

    if args.name:
        method = get_method(args.name)
        return method.to_dict(), method.describe()
    width = max(len(name) for name in METHODS)
    text = "\n".join(f"{name:<{width}}  {METHODS.summary(name)}" for name in METHODS)
    text += "\n\n'servoid methods NAME' shows a method's [identify] keys."
    if not args.json:  # the list needs no method loaded; the JSON gives every method's keys
        return {}, text
    return {"methods": [METHODS[name].to_dict() for name in METHODS]}, text


def _run_identify(args: argparse.Namespace) -> tuple[dict[str, Any], str]:
    from .._flags import at_least
    from ..workflows import identify

    if args.max_bytes is not None:
        at_least("--max-bytes", args.max_bytes, 1)
    result = identify(args.experiment, args.out, overwrite=args.overwrite,
                      allow_outside=args.allow_outside, max_bytes=args.max_bytes,
                      allow_code=args.allow_code)
    return result.to_dict() | {"files": [str(f) for f in result.files]}, str(result)
