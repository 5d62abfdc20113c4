"""``servoid export`` (a run's models as ``.mat``, model JSON or Python) and ``servoid report``."""

from __future__ import annotations

import argparse
import keyword
import math
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from .._flags import out_path

__all__ = ["add_export"]

_SUFFIX = {"mat": ".mat", "json": ".json", "python": ".py"}


def add_export(commands: Any, json_flag: Callable[[argparse.ArgumentParser], None]) -> None:
    """Add ``servoid export`` and ``servoid report``."""
    export = commands.add_parser(
        "export", help="write the identified model(s) for MATLAB, python-control or servoid",
        description="Read the results.json of 'servoid identify' and write its model(s): "
        "--to mat (one MATLAB struct per model: num/den/Ts, A/B/C/D/Ts or idpoly's "
        "A/B/C/D/F/nk/Ts, plus InputDelay and type), --to json (a servoid model file, read "
        "back with servoid.load_model) or --to python (a script that rebuilds the "
        "model with python-control). A black-box method writes one model, G; the closed-loop "
        "method writes each approach's continuous plant and closed loop. A nonlinear model "
        "(narx, hammerstein, wiener, hammerstein-wiener) and a grey-box ODE (greybox) go "
        "--to json only: MATLAB and python-control have no form for them. Writing a grey-box "
        "model's file runs no code: it names the Python file (path and SHA-256), which "
        "servoid.load_model runs only with allow_code=True.",
    )
    export.add_argument("results", type=Path, help="results.json written by servoid identify")
    export.add_argument("--to", required=True, choices=sorted(_SUFFIX),
                        help="output format")
    export.add_argument("--model", metavar="NAME",
                        help="export only this model (the command lists the names)")
    export.add_argument("--candidate", metavar="LABEL",
                        help="of a multi-method run (method = [...] or \"auto\"): export this "
                        "candidate of its leaderboard instead of the chosen model")
    export.add_argument("--out", type=out_path, help="file to write (default: model.mat, "
                        "model.json or model.py beside RESULTS; model_NAME.* with --model)")
    export.add_argument("--overwrite", action="store_true", help="replace an existing file")
    json_flag(export)
    export.set_defaults(run=_run_export)

    report = commands.add_parser(
        "report", help="write the report of a run again",
        description="Write report.html, the figures and results.json of a run again from the "
        "experiment file it names, after checking that every input is byte-for-byte the one "
        "the run read (the SHA-256 in its manifest.json); a changed input is refused. "
        "Only files in the run's folder or named on the command line are read: an "
        "experiment file elsewhere (the usual <experiment>-results layout) is named with "
        "--experiment. The identification runs again, so a grey-box run (method = "
        "\"greybox\") needs --allow-code, and its Python model file must be unchanged too; "
        "the code that runs is the bytes that were checked.",
    )
    report.add_argument("results", type=Path, help="results.json written by servoid identify")
    report.add_argument("--experiment", type=out_path, metavar="TOML",
                        help="the run's experiment file, when it is not in the run's folder "
                        "(it must be the file the run read)")
    report.add_argument("--out", type=out_path,
                        help="folder for the new report (default: the run's own folder)")
    report.add_argument("--overwrite", action="store_true",
                        help="replace files in --out that are not the run's own")
    report.add_argument("--allow-code", action="store_true",
                        help="let a grey-box run's Python model file run again (method = "
                        "\"greybox\"); check the file first")
    json_flag(report)
    report.set_defaults(run=_run_report)


def _run_report(args: argparse.Namespace) -> tuple[dict[str, Any], str]:
    from ..workflows import rerender

    result = rerender(args.results, args.out, experiment=args.experiment,
                      allow_code=args.allow_code, overwrite=args.overwrite)
    return ({"files": [str(f) for f in result.files]},
            f"{result}\nwritten: {result.folder}")


def _run_export(args: argparse.Namespace) -> tuple[dict[str, Any], str]:
    from .._atomic import atomic_path
    from .._errors import DataError, ModelError, OptionError
    from ..models import RECORD_TYPES, record_text, write_mat
    from ..workflows import greybox_record, load_results

    # a grey-box run: its model file is written from the record, without running its code
    record = greybox_record(args.results)
    if record is None:
        loaded = load_results(args.results)
        models: dict[str, Any] = dict(loaded.models)
        data = loaded.data
    else:
        models, data = {"G": record}, {}
    if getattr(args, "candidate", None) is not None:
        models, data = _candidate(args.results, args.candidate)
    if not models:
        method = loaded.data.get("method") or "this method"
        raise ModelError(
            f"{args.results} holds no model to export (written by {method}, whose result is "
            "not a transfer "
            "function, state space, polynomial, NARX or block model); export works on the "
            "results of the black-box methods (arx, oe, armax, bj, tf, n4sid, two-stage, cliv, "
            "indirect), of closedloop and of the nonlinear methods (narx, hammerstein, wiener, "
            "hammerstein-wiener, greybox)")
    if args.model is not None:
        if args.model not in models:
            raise OptionError(f"--model must be one of {', '.join(models)} (the models of "
                              f"{args.results}); got {args.model!r}")
        models = {args.model: models[args.model]}
    nonlinear = [n for n, m in models.items() if _kind(m) in RECORD_TYPES]
    if nonlinear and args.to != "json":
        target = "MATLAB's tf/ss/idpoly" if args.to == "mat" else "python-control"
        kinds = ", ".join(sorted({_kind(models[n]) for n in nonlinear}))
        consent = ", allow_code=True" if record is not None else ""  # it runs the user's file
        raise ModelError(
            f"{args.results} holds a nonlinear model ({kinds}) and {target} has no form for "
            f"it: use --to json, which writes a servoid model file, and read it back in Python "
            f"with servoid.load_model(\"model.json\"{consent}) to simulate or validate it")
    if args.to == "json" and len(models) > 1:
        raise OptionError(f"{args.results} holds {len(models)} models ({', '.join(models)}) and "
                          "a model file holds one: pick one with --model NAME, or write them "
                          "all with --to mat or --to python")
    suffix = _SUFFIX[args.to]
    out = args.out
    if out is None:
        stem = "model" if args.model is None else f"model_{args.model}"
        out = args.results.parent / f"{stem}{suffix}"
    elif out.suffix.lower() != suffix:
        raise DataError(f"--out {out} does not end in {suffix}, which --to {args.to} writes: "
                        f"name the file {out.with_suffix(suffix).name}, or pick the --to "
                        "that matches it")
    _refuse_inputs(out, args.results, record)
    if args.to == "mat":
        write_mat(models, out, overwrite=args.overwrite)
    else:
        if args.to == "json":
            text = record_text(_json_record(next(iter(models.values())), data))
        else:
            text = _python(models, args.results)
        with atomic_path(out, args.overwrite) as tmp:
            tmp.write_text(text, encoding="utf-8")
    names = ", ".join(f"{n} ({_kind(m)})" for n, m in models.items())
    return ({"results": str(args.results), "to": args.to, "file": str(out),
             "models": {n: _kind(m) for n, m in models.items()}},
            f"wrote {out}: {names}")


# -- private ------------------------------------------------------------------------------


def _candidate(results: Path, label: str) -> tuple[dict[str, Any], dict[str, Any]]:
    """``--candidate``: one candidate's model of a multi-method run, as G, and its entry."""
    from .._errors import OptionError
    from ..workflows import candidate_models

    models, rows = candidate_models(results)
    if label not in models:
        raise OptionError(f"--candidate must be one of {', '.join(map(repr, models))} (the "
                          f"candidates of {results} with a model); got {label!r}")
    return {"G": models[label]}, {"model": rows[label].get("model")}


def _kind(model: Any) -> str:
    """A model's type name; a grey-box model stays its record (its code is not run)."""
    return str(model["type"]) if isinstance(model, dict) else type(model).__name__


def _json_record(model: Any, data: Mapping[str, Any]) -> dict[str, Any]:
    """A model file's data, with the covariance the run kept."""
    # a NarxModel's record holds its own covariance; a block model's sits in results.json
    from ..models import model_record

    if isinstance(model, dict):  # a grey-box model's record, complete with its covariance
        return {**model, "units": None}

    record = model_record(model)
    entry = data.get("model")
    if record.get("covariance") is None and type(model).__name__ == "BlockModel" and \
            isinstance(entry, Mapping) and entry.get("covariance") is not None:
        record["covariance"] = entry["covariance"]
        record["parameter_names"] = entry.get("parameter_names")
    record.setdefault("covariance", None)
    record["units"] = None
    return record


def _python(models: Mapping[str, Any], results: Path) -> str:
    """A python-control script; every string in it is a ``repr`` literal, never raw text.

    A file or model name may hold quotes, newlines or code: it enters the
    script only as a Python string literal (``repr``) or a checked
    identifier, so running the script runs nothing but the models.
    """
    from .._errors import ModelError
    from ..models import PolynomialModel, StateSpace, TransferFunction

    doc = f"Models exported by servoid from {results.name}; needs python-control."
    lines = [repr(doc), "", "import control", "", "models = {}"]
    for name, model in models.items():
        if isinstance(model, PolynomialModel):
            if model.n_inputs != 1:
                raise ModelError(f"{name} is a PolynomialModel with {model.n_inputs} inputs and "
                                 "control.tf holds one; export it --to mat or --to json")
            lines.append(f"# {name!r}: transfer function from the input; the noise model "
                         "C/(A·D) is not exported")
            model = model.transfer_function(input=0)
        dt = 0 if model.dt is None else model.dt
        if isinstance(model, TransferFunction):
            if model.delay:
                raise ModelError(
                    f"{name} has a delay of {model.delay!r} s and python-control transfer "
                    "functions have none; export it --to mat or --to json (both keep "
                    "InputDelay), or discretise it with servoid.models.c2d first")
            value = f"control.tf({_list(model.num)}, {_list(model.den)}, {_float(dt)})"
        elif isinstance(model, StateSpace):
            mats = ", ".join(_list(getattr(model, k)) for k in "ABCD")
            value = f"control.ss({mats}, {_float(dt)})"
        else:
            continue
        lines.append(f"models[{name!r}] = {value}")
        if name.isidentifier() and not keyword.iskeyword(name) and name != "models" \
                and name != "control" and name.isascii():
            lines.append(f"{name} = models[{name!r}]")
    return "\n".join(lines) + "\n"


def _float(value: float) -> str:
    """A float as Python source: ``repr`` reads back exactly; inf and nan spelled out."""
    value = float(value)
    return repr(value) if math.isfinite(value) else f"float({str(value)!r})"


def _list(values: Any) -> str:
    """Nested lists of floats as Python source (repr of each float: exact)."""
    import numpy as np

    def source(v: Any) -> str:
        if isinstance(v, list):
            return "[" + ", ".join(source(x) for x in v) + "]"
        return _float(v)

    return source(np.asarray(values, dtype=float).tolist())


def _refuse_inputs(out: Path, results: Path, record: Mapping[str, Any] | None) -> None:
    """The export never writes over what it reads, ``--overwrite`` or not."""
    from .._errors import OutputExistsError

    inputs = [results, results.parent / "manifest.json"]
    if record is not None:  # a grey-box model's code: named, never written
        inputs += [Path(record[k]) for k in ("model_file", "output_file")
                   if isinstance(record.get(k), str)]
    target = out.resolve()
    for path in inputs:
        if target == path.resolve():
            raise OutputExistsError(f"refusing to write {out}: it is {path}, an input of this "
                                    "export (--overwrite never replaces an input); choose "
                                    "another --out")
