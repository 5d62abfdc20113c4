"""The bad-input catalogue of servoid's documents (issue 21, items 6 and 7).

Every class of bad input the loader fuzzers (``test_loader_fuzz.py``) and
the audit found, in every document that can hold it: the model file
(:func:`servoid.load_model`), ``results.json`` and its ``manifest.json``
(:func:`servoid.load_results`, :func:`servoid.workflows.rerender`), the
experiment file (:func:`servoid.data.load_experiment_spec`) and the fleet
file.  The classes:

- nesting too deep for the parser (arrays and objects / inline tables);
- an integer past the float range (10**400) where a number belongs, and one
  past Python's 4300-digit limit;
- a value of the wrong type or shape in each field a loader reads;
- a path that names no file: a NUL character, a lone surrogate, a name over
  255 bytes;
- CSV options the reader cannot use (``delimiter = "narx"``);
- a model record of the wrong kind (an unhashable ``type``, a block whose
  linear block is a block);
- a file that is no regular UTF-8 file (a folder, UTF-16 text) and a
  damaged manifest.

Each case builds a document from a valid one (the loader fuzzers' seeds in
``loader_seeds/``, or an experiment file written here), breaks one thing and
checks the error class and its built-in, a message naming the field, the
value or the problem and the fix, and that the folder is as it was.  A few
``api-`` cases put the same integer into number arguments.  A case whose fix
is still to come would be a strict ``xfail`` naming the file to change (it
fails once fixed, so the mark goes with the fix); none is left.
"""

from __future__ import annotations

import hashlib
import json
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from servoid import (
    DataError,
    Experiment,
    FileFormatError,
    MissingFileError,
    ModelError,
    OptionError,
    OutputExistsError,
    ServoidError,
    load_model,
    load_results,
)
from servoid.data import load_experiment_spec
from servoid.fleet import load_fleet_spec
from servoid.models import TransferFunction
from servoid.signals import prbs
from servoid.workflows import rerender

SEEDS = Path(__file__).resolve().parent / "loader_seeds"
BUILTIN = {FileFormatError: ValueError, DataError: ValueError, OptionError: ValueError, ModelError: ValueError,
           MissingFileError: FileNotFoundError, OutputExistsError: FileExistsError}
BIG = 10**400  # past the largest float, 1.8e308
DIGITS = "9" * 5000  # past Python's int/str limit of 4300 digits
DEEP_ARRAYS = "[" * 100_000 + "]" * 100_000
DEEP_JSON_OBJECTS = '{"a":' * 100_000 + "1" + "}" * 100_000
DEEP_TOML_TABLES = "{a = " * 100_000 + "1" + "}" * 100_000
LONG_NAME = "x" * 300 + ".csv"

# -- documents ---------------------------------------------------------------------------------

Edit = Callable[[Any], Any]


def seed(kind: str, name: str, folder: Path) -> Any:
    """A seed document with its placeholder folders put in ``folder``."""
    text = (SEEDS / kind / f"{name}.json").read_text(encoding="utf-8")
    return json.loads(text.replace("@RUN@", str(folder)).replace("@CODE@", str(folder)))


def put(path: str, value: Any) -> Edit:
    """Set the field at a dotted path (``estimate.parameters.0.value``)."""
    def edit(doc: Any) -> Any:
        *parents, last = [int(p) if p.isdigit() else p for p in path.split(".")]
        node = doc
        for p in parents:
            node = node[p]
        node[last] = value
        return doc
    return edit


def drop(path: str) -> Edit:
    def edit(doc: Any) -> Any:
        *parents, last = [int(p) if p.isdigit() else p for p in path.split(".")]
        node = doc
        for p in parents:
            node = node[p]
        del node[last]
        return doc
    return edit


def raw(field: str, text: str) -> Edit:
    """Put raw JSON text at a top-level field (numbers and nesting Python cannot dump)."""
    def edit(doc: Any) -> str:
        doc[field] = "@RAW@"
        return json.dumps(doc).replace('"@RAW@"', text)
    return edit


def _write(target: Path, doc: Any) -> None:
    if isinstance(doc, bytes):
        target.write_bytes(doc)
    else:
        target.write_text(doc if isinstance(doc, str) else json.dumps(doc), encoding="utf-8")


def model_call(name: str, edit: Edit, allow_code: bool = False) -> Callable[[Path], Any]:
    def call(folder: Path) -> Any:
        _write(folder / "model.json", edit(seed("models", name, folder)))
        _freeze_folder(folder)
        return load_model(folder / "model.json", allow_code=allow_code)
    return call


def results_call(name: str, edit: Edit, manifest: Edit | None = None,
                 how: str = "load") -> Callable[[Path], Any]:
    def call(folder: Path) -> Any:
        _write(folder / "results.json", edit(seed("results", name, folder)))
        if how != "rerender-no-manifest":
            _write(folder / "manifest.json", (manifest or (lambda d: d))(
                seed("results", f"{name}.manifest", folder)))
        _freeze_folder(folder)
        if how.startswith("rerender"):
            return rerender(folder / "results.json", folder / "again", allow_code=True)
        return load_results(folder / "results.json")
    return call


SPEC = """\
[data]
file = "data.csv"
time = "time"

[channels.u]
role = "u"

[channels.y]
role = "y"
"""


def spec_call(text: str | bytes) -> Callable[[Path], Any]:
    def call(folder: Path) -> Any:
        (folder / "data.csv").write_text("time,u,y\n0.0,1.0,2.0\n0.1,1.0,2.0\n",
                                         encoding="utf-8")
        _write(folder / "exp.toml", text)
        _freeze_folder(folder)
        return load_experiment_spec(folder / "exp.toml")
    return call


FLEET = """\
[records]
glob = "runs/*.toml"

[limits.a1]
nominal = -0.8
tolerance = 0.1
"""


def fleet_call(text: str) -> Callable[[Path], Any]:
    def call(folder: Path) -> Any:
        (folder / "runs").mkdir()
        (folder / "runs" / "a.toml").write_text(SPEC, encoding="utf-8")
        (folder / "fleet.toml").write_text(text, encoding="utf-8")
        _freeze_folder(folder)
        return load_fleet_spec(folder / "fleet.toml")
    return call


def case(case_id: str, call: Callable[[Path], Any], error: type[ServoidError], match: str,
         xfail: str | None = None) -> Any:
    marks = [pytest.mark.xfail(strict=True, reason=xfail)] if xfail else []
    return pytest.param(call, error, match, id=case_id, marks=marks)


def spec_with(table: str, line: str) -> str:
    """SPEC with ``line`` added at the end of ``[table]`` (a new table when absent)."""
    header = f"[{table}]\n"
    if header not in SPEC:
        return SPEC + "\n" + header + line + "\n"
    head, tail = SPEC.split(header)
    body, sep, rest = tail.partition("\n[")
    return head + header + body + line + "\n" + sep + rest


# -- the catalogue -----------------------------------------------------------------------------

NESTED = "nested too deeply to read"
PAST = r"is an integer past the largest float \(1\.8e308\)"
DAMAGED_MODEL = r"write it again with servoid\.models\.save_model"
DAMAGED_RESULTS = r"write it again with servoid identify"

CASES = [
    # nesting too deep for the parser ----------------------------------------------------------
    case("model-deep-arrays", model_call("tf-continuous", raw("num", DEEP_ARRAYS)),
         FileFormatError, rf"model\.json is not valid JSON for servoid.*{NESTED}.*{DAMAGED_MODEL}"),
    case("model-deep-objects", model_call("tf-continuous", raw("units", DEEP_JSON_OBJECTS)),
         FileFormatError, rf"model\.json is not valid JSON for servoid.*{NESTED}"),
    case("results-deep-arrays", results_call("arx", raw("notes", DEEP_ARRAYS)),
         FileFormatError, rf"results\.json is not valid JSON for servoid.*{NESTED}"),
    case("results-deep-objects", results_call("arx", raw("truth", DEEP_JSON_OBJECTS)),
         FileFormatError, rf"results\.json is not valid JSON for servoid.*{NESTED}"),
    case("manifest-deep", results_call("arx", lambda d: d, raw("files", DEEP_ARRAYS), "rerender"),
         FileFormatError, rf"manifest\.json is not valid JSON for servoid.*{NESTED}.*cannot be "
         "checked; write the run again with servoid identify"),
    case("spec-deep-arrays", spec_call(spec_with("identify", f"orders = {DEEP_ARRAYS}")),
         FileFormatError, r"exp\.toml: not a valid TOML file \(its arrays or inline tables are "
         r"nested too deeply to read; an experiment file needs at most two levels\)"),
    case("spec-deep-tables", spec_call(spec_with("identify", f"orders = {DEEP_TOML_TABLES}")),
         FileFormatError, r"exp\.toml: not a valid TOML file \(its arrays or inline tables"),
    case("fleet-deep-arrays", fleet_call(FLEET + f"[report]\nfolder = {DEEP_ARRAYS}\n"),
         FileFormatError, r"fleet file .*fleet\.toml: not a valid TOML file \(its arrays"),
    # an integer past the float range ----------------------------------------------------------
    case("model-tf-num-1e400", model_call("tf-continuous", put("num.1", BIG)),
         FileFormatError, rf"model\.json: num\[1\] {PAST}.*{DAMAGED_MODEL}"),
    case("model-dt-1e400", model_call("arx-G", put("dt", BIG)),
         FileFormatError, rf"dt {PAST}"),
    case("model-noise-variance-1e400", model_call("arx-estimate", put("noise_variance", -BIG)),
         FileFormatError, rf"noise_variance {PAST}"),
    case("model-narx-coefficient-1e400", model_call("narx-G", put("coefficients.2", BIG)),
         FileFormatError, rf"coefficients\[2\] {PAST}"),
    case("model-block-offset-1e400", model_call("block-hw", put("offset", BIG)),
         FileFormatError, rf"offset {PAST}"),
    case("model-block-linear-1e400", model_call("block-hw", put("linear.den.1", BIG)),
         FileFormatError, rf"linear\.den\[1\] {PAST}"),
    case("model-greybox-parameter-1e400",
         model_call("greybox-G", put("parameters.0.value", BIG), allow_code=True),
         FileFormatError, rf"parameters\[0\]\.value {PAST}"),
    case("model-ss-matrix-1e400", model_call("ss-zoh", put("A.0.1", BIG)),
         FileFormatError, rf"A\[0\]\[1\] {PAST}"),
    case("results-parameter-1e400", results_call("arx", put("estimate.parameters.0.value", BIG)),
         FileFormatError, rf"results\.json: estimate\.parameters\[0\]\.value {PAST}.*"
         rf"{DAMAGED_RESULTS}"),
    case("results-model-1e400", results_call("tf", put("model.den.0", BIG)),
         FileFormatError, rf"model\.den\[0\] {PAST}"),
    case("results-closedloop-1e400",
         results_call("closedloop", put("approaches.one-step.plant_continuous.num.0", BIG)),
         FileFormatError, rf"approaches\.one-step\.plant_continuous\.num\[0\] {PAST}"),
    case("spec-dt-1e400", spec_call(spec_with("data", f"dt = {BIG}")),
         FileFormatError, r"\[data\] dt must be a finite number \(within ±1\.8e308\), got int "
         r"1000000000"),
    case("spec-gain-1e400", spec_call(spec_with("channels.u", f"gain = -{BIG}")),
         FileFormatError, r"\[channels\.u\] gain must be a finite number \(within ±1\.8e308\)"),
    case("spec-limits-1e400", spec_call(spec_with("channels.y", f"limits = [0.0, {BIG}]")),
         FileFormatError, r"\[channels\.y\] limits must be a finite number"),
    case("spec-lowpass-1e400", spec_call(spec_with("preprocess", f"lowpass = {BIG}")),
         FileFormatError, r"\[preprocess\] lowpass must be a finite number"),
    case("spec-cutoff-1e400",
         spec_call(spec_with("rig", f"anti_alias = {{order = 2, cutoff = {BIG}}}")),
         FileFormatError, r"\[rig\] anti_alias cutoff must be a finite number"),
    case("spec-max-bytes-1e400", spec_call(spec_with("data", f"max_bytes = {BIG}")),
         FileFormatError, r"\[data\] max_bytes must be an integer below 2\*\*63, got int 1000"),
    case("spec-decimate-2-64", spec_call(spec_with("preprocess", f"decimate = {2**64}")),
         FileFormatError, r"\[preprocess\] decimate must be an integer below 2\*\*63, got int "
         r"18446744073709551616"),
    case("fleet-limit-1e400", fleet_call(FLEET.replace("nominal = -0.8", f"nominal = {BIG}")),
         OptionError, r"nominal must be a finite number \(at most about 1\.8e308\); got a larger "
         r"integer"),
    # the same class through the API (a number argument, not a document)
    case("api-tf-num-1e400", lambda folder: TransferFunction([BIG], [1.0, 1.0]),
         ModelError, r"num must hold numbers within ±1\.8e308, got an integer too large"),
    case("api-tf-dt-1e400", lambda folder: TransferFunction([1.0], [1.0, 1.0], dt=BIG),
         ModelError, r"dt must be > 0 s \(None for continuous time\), got 10000"),
    case("api-prbs-dt-1e400", lambda folder: prbs(5, dt=BIG), DataError,
         r"dt must be finite s \(within ±1\.8e308\), got an integer too large"),
    case("api-experiment-dt-1e400",
         lambda folder: Experiment.from_arrays(BIG, u=[1.0, 2.0, 3.0]), DataError,
         r"dt must be a finite number of seconds > 0, got an integer too large"),
    # an integer past Python's digit limit -----------------------------------------------------
    case("model-5000-digits", model_call("tf-continuous", raw("delay", DIGITS)),
         FileFormatError, r"model\.json is not valid JSON for servoid: Exceeds the limit \(4300 "
         r"digits\).*\(no number servoid writes has that many\)"),
    case("results-5000-digits", results_call("arx", raw("truth", DIGITS)),
         FileFormatError, r"results\.json is not valid JSON for servoid: Exceeds the limit"),
    case("spec-5000-digits", spec_call(spec_with("data", f"dt = {DIGITS}")),
         FileFormatError, r"exp\.toml: not a valid TOML file \(Exceeds the limit \(4300 digits\).*"
         r"no setting takes a number that long\)"),
    case("fleet-5000-digits", fleet_call(FLEET.replace("-0.8", DIGITS)),
         FileFormatError, r"fleet\.toml: not a valid TOML file \(Exceeds the limit"),
    # wrong types and shapes in results.json ---------------------------------------------------
    case("results-version-number", results_call("arx", put("servoid_version", 1)),
         FileFormatError, r"servoid_version must be a string, got int 1; the file is damaged"),
    case("results-method-list", results_call("arx", put("method", ["arx"])),
         FileFormatError, r"method must be a string, got an array \['arx'\]"),
    case("results-model-list", results_call("arx", put("model", [1, 2])),
         FileFormatError, r"model must be an object \{\.\.\.\}, got an array \[1, 2\]"),
    case("results-model-b-number", results_call("arx", put("model.b", 3)),
         FileFormatError, r"model\.b must be an array \[\.\.\.\], got int 3"),
    case("results-model-nk-text", results_call("arx", put("model.nk", "1")),
         FileFormatError, r"model\.nk must be an array"),
    case("results-model-type-object", results_call("arx", put("model.type", {})),
         FileFormatError, r"model\.type must be a string, got an object \{\}"),
    case("results-model-coefficients-text", results_call("tf", put("model.num", "1 2")),
         FileFormatError, r"results\.json: model is not a valid TransferFunction \(.*num"),
    case("results-block-linear-block",
         results_call("hammerstein", lambda d: put("model.linear", dict(d["model"]))(d)),
         FileFormatError, r"model\.linear\.type must be \"transfer_function\" or \"polynomial\""),
    case("results-block-static-list", results_call("hammerstein",
                                                   put("model.input_nonlinearity", [1])),
         FileFormatError, r"model\.input_nonlinearity must be an object"),
    case("results-estimate-parameters-object", results_call("arx", put("estimate.parameters", {})),
         FileFormatError, r"estimate\.parameters must be an array \[\.\.\.\], got an object"),
    case("results-estimate-parameters-null", results_call("arx", put("estimate.parameters", None)),
         FileFormatError, r"estimate\.parameters must be an array \[\.\.\.\], got null"),
    case("results-parameter-value-text",
         results_call("arx", put("estimate.parameters.1.value", "0.5")),
         FileFormatError, r"estimate\.parameters\[1\]\.value must be a number or null, got the "
         r"string '0\.5'"),
    case("results-parameter-name-number", results_call("arx", put("estimate.parameters.0.name", 7)),
         FileFormatError, r"estimate\.parameters\[0\]\.name must be a string, got int 7"),
    case("results-parameter-ci95-three",
         results_call("arx", put("estimate.parameters.0.ci95", [1, 2, 3])),
         FileFormatError, r"estimate\.parameters\[0\]\.ci95 must be \[low, high\] or null"),
    case("results-validation-list", results_call("arx", put("validation", [1])),
         FileFormatError, r"results\.json: validation must be an object \{\.\.\.\}, got an array"),
    case("results-residuals-number", results_call("arx", put("validation.residuals", 3.5)),
         FileFormatError, r"validation\.residuals must be an object \{\.\.\.\}, got float 3\.5"),
    case("results-is-white-text", results_call("arx", put("validation.residuals.is_white", "no")),
         FileFormatError, r"validation\.residuals\.is_white must be true, false or null, got the "
         r"string 'no'"),
    case("results-fit-text", results_call("arx", put("validation.fit_percent", "99 %")),
         FileFormatError, r"validation\.fit_percent must be a number or null"),
    case("results-diverged-time-text",
         results_call("arx", put("validations.0.diverged_at", {"sample": 3, "time": "soon"})),
         FileFormatError, r"validations\[0\]\.diverged_at\.time must be a number or null"),
    case("results-estimates-entry-list", results_call("arx", lambda d: put(
        "estimates", {"first": [1]})(drop("estimate")(d))),
         FileFormatError, r"estimates\.first must be an object"),
    case("results-closedloop-approaches-null", results_call("closedloop", put("approaches", None)),
         FileFormatError, r"approaches must be an object \{\.\.\.\}, got null"),
    case("results-closedloop-approach-text",
         results_call("closedloop", put("approaches.one-step", "fast")),
         FileFormatError, r"approaches\.one-step must be an object"),
    case("results-closedloop-flags-null",
         results_call("closedloop", put("approaches.one-step.flags", None)),
         FileFormatError, r"approaches\.one-step\.flags must be an array \[\.\.\.\], got null"),
    case("results-closedloop-ci95-null",
         results_call("closedloop", put("parameters.0.one-step.ci95", None)),
         FileFormatError, r"parameters\[0\]\.one-step\.ci95 must be \[low, high\]"),
    case("results-closedloop-row-text", results_call("closedloop", put("parameters.1", "K")),
         FileFormatError, r"parameters\[1\] must be an object"),
    case("results-closedloop-plant-list",
         results_call("closedloop", put("approaches.indirect.plant_continuous", [1.0])),
         FileFormatError, r"approaches\.indirect\.plant_continuous must be an object"),
    case("results-structure-test-list", results_call("closedloop", put("structure_test", [1])),
         FileFormatError, r"structure_test must be an object"),
    case("results-experiment-file-number", results_call("arx", put("experiment_file", 3)),
         FileFormatError, r"experiment_file must be a string, got int 3"),
    case("results-greybox-model-file-list", results_call("greybox", put("model.model_file", [])),
         FileFormatError, r"model\.model_file must be an object"),
    # a path that names no file ----------------------------------------------------------------
    case("spec-file-nul", spec_call(SPEC.replace('"data.csv"', '"da\\u0000ta.csv"')),
         FileFormatError, r"\[data\] file = 'da\\x00ta\.csv' holds a NUL character \(\\u0000\), "
         r"which no file name can: write the rig file's name"),
    case("spec-validation-file-nul",
         spec_call(SPEC + '\n[validation]\nfile = ["ok.csv", "v\\u0000.csv"]\n'),
         FileFormatError, r"\[validation\] file = 'v\\x00\.csv' holds a NUL character"),
    case("spec-file-too-long", spec_call(SPEC.replace("data.csv", LONG_NAME)),
         FileFormatError, r"\[data\] file = 'xxxx.* has a name of 304 bytes; file systems allow "
         r"255: write the rig file's name"),
    case("results-experiment-file-nul",
         results_call("arx", put("experiment_file", "/tmp/e\x00xp.toml")),
         FileFormatError, r"experiment_file = '/tmp/e\\x00xp\.toml' holds a NUL character.*names "
         r"no file; the file is damaged: write it again with servoid identify"),
    case("results-experiment-file-surrogate",
         results_call("arx", put("experiment_file", "/tmp/\ud800.toml")),
         FileFormatError, r"experiment_file = .* holds a character this system cannot write in a "
         r"file name \(a lone UTF-16 surrogate\)"),
    case("manifest-path-nul", results_call("arx", lambda d: d, put("inputs.0.path", "/tmp/a\x00b"),
                                           "rerender"),
         FileFormatError, r"manifest .*manifest\.json: inputs\[0\]\.path = '/tmp/a\\x00b' holds a "
         r"NUL character"),
    case("manifest-path-too-long", results_call("arx", lambda d: d, put(
        "inputs.0.path", "/tmp/" + "d/" * 3000 + "x.csv"), "rerender"),
         FileFormatError, r"inputs\[0\]\.path = .* is 6010 bytes long; paths stop at 4095"),
    case("greybox-model-file-nul",
         model_call("greybox-G", lambda d: put(
             "model_file", d["model_file"].replace("tanks", "ta\x00nks"))(d), allow_code=True),
         FileFormatError, r"model\.json: model_file = '/.*/ta\\x00nks\.py'( \(\d+ characters\))? "
         r"holds a NUL character "
         r"\(\\u0000\), which no file name can; the file is damaged: write it again with "
         r"servoid\.models\.save_model"),
    # CSV options in the experiment file ------------------------------------------------------
    case("spec-delimiter-word", spec_call(spec_with("data", 'delimiter = "narx"')),
         FileFormatError, r"\[data\] delimiter must be the one character between fields \(\",\", "
         r"\";\" or \"\\t\" for a tab\), got 'narx'; set it to the separator the file uses"),
    case("spec-delimiter-quote", spec_call(spec_with("data", "delimiter = '\"'")),
         FileFormatError, r"\[data\] delimiter must be the one character between fields"),
    case("spec-delimiter-newline", spec_call(spec_with("data", 'delimiter = "\\n"')),
         FileFormatError, r"\[data\] delimiter must be the one character between fields"),
    case("spec-decimal-semicolon", spec_call(spec_with("data", 'decimal = ";"')),
         FileFormatError, r"\[data\] decimal must be one of '\.', ',', got ';'"),
    case("spec-decimal-comma-default-delimiter", spec_call(spec_with("data", 'decimal = ","')),
         FileFormatError, r"\[data\]: decimal = ',' is also the field separator; set delimiter = "
         r"\";\""),
    case("spec-time-unit-hours", spec_call(spec_with("data", 'time_unit = "h"')),
         FileFormatError, r"\[data\] time_unit must be one of 's', 'ms', 'us', 'µs', got 'h'"),
    # messages that say what to write ---------------------------------------------------------
    case("spec-no-data", spec_call(SPEC.replace("[data]\n", "[report]\n")),
         FileFormatError, r"the top level is missing the required key\(s\) data; add a \[data\] "
         r"table with file = \"<rig file>\""),
    case("spec-no-file", spec_call(SPEC.replace('file = "data.csv"\n', "")),
         FileFormatError, r"\[data\] is missing the required key\(s\) file; add file = \"<rig "
         r"file>\" \(relative to the experiment file\)"),
    case("spec-anti-alias-empty", spec_call(spec_with("rig", "anti_alias = {}")),
         FileFormatError, r"\[rig\] anti_alias is missing the required key\(s\) order, cutoff; "
         r"add order = <1\.\.10>; cutoff = <Hz>"),
    case("spec-skip-periods-alone", spec_call(spec_with("split", "skip_periods = 2")),
         FileFormatError, r"skip_periods needs period; add period = <samples per excitation "
         r"period>, or remove skip_periods"),
    case("spec-free-table-too-deep", spec_call(spec_with("loop", "a = {b = {c = 1}}")),
         FileFormatError, r"table 'b' is nested more than one level deep; .*flatten it"),
    case("spec-group-csv", spec_call(spec_with("data", 'group = "g"')),
         FileFormatError, r"group applies to TDMS files only, this is csv: remove group"),
    case("spec-unknown-long-key", spec_call(spec_with("data", "k" * 500 + " = 1")),
         OptionError, r"unknown key\(s\) in \[data\]: 'kkkk.*\(502 characters\); valid keys"),
    # a model record of the wrong kind --------------------------------------------------------
    case("model-type-object", model_call("tf-continuous", put("type", {"a": 1})),
         FileFormatError, r"\"type\" must be one of 'TransferFunction'.*got \{'a': 1\}"),
    case("model-type-list", model_call("tf-continuous", put("type", ["StateSpace"])),
         FileFormatError, r"\"type\" must be one of .*got \['StateSpace'\]"),
    case("model-type-long", model_call("tf-continuous", put("type", "T" * 5000)),
         FileFormatError, r"got 'TTTT.*…T*' \(5002 characters\)"),
    case("model-block-linear-block",
         model_call("block-hw", lambda d: put("linear", json.loads(json.dumps(d)))(d)),
         FileFormatError, r"the BlockModel's \"linear\" must be the record of a TransferFunction "
         r"or PolynomialModel, got 'BlockModel'"),
    case("model-block-linear-narx", model_call(
        "block-hw", lambda d: put("linear", seed("models", "narx-G", Path("/")))(d)),
         FileFormatError, r"\"linear\" must be the record of .*got 'NarxModel'"),
    case("model-block-linear-list", model_call("block-hw", put("linear", [1])),
         FileFormatError, r"the BlockModel is damaged \(the linear block is not a servoid model "
         r"file"),
    case("model-version-object", model_call("tf-continuous", put("servoid_model", {"v": 1})),
         FileFormatError, r"has format version \{'v': 1\}; this servoid reads version 1"),
    # not a regular UTF-8 file, a damaged manifest --------------------------------------------
    case("model-folder", lambda folder: load_model(folder), FileFormatError,
         r"model file .* is a folder, not a regular file; pass the path of a file"),
    case("results-folder", lambda folder: load_results(folder), FileFormatError,
         r"results file .* is a folder, not a regular file"),
    case("model-link-loop", lambda folder: (
        (folder / "a.json").symlink_to(folder / "b.json"),
        (folder / "b.json").symlink_to(folder / "a.json"), load_model(folder / "a.json")),
         FileFormatError, r"a\.json is a symbolic link that loops \(it leads back to itself "
         r"through one or more links\): fix the link or pass the file itself"),
    case("model-utf16", model_call("tf-continuous", lambda d: json.dumps(d).encode("utf-16")),
         FileFormatError, r"model\.json is UTF-16 text \(its byte-order mark says so\); servoid "
         r"reads JSON files in UTF-8: save it as UTF-8"),
    case("results-utf16", results_call("arx", lambda d: json.dumps(d).encode("utf-16")),
         FileFormatError, r"results\.json is UTF-16 text"),
    case("spec-utf16", spec_call(SPEC.encode("utf-16")),
         FileFormatError, r"exp\.toml is UTF-16 text .*servoid reads TOML files in UTF-8"),
    case("spec-latin1", spec_call(SPEC.replace("[channels.y]", "# é\n[channels.y]")
                                  .encode("latin-1")),
         FileFormatError, r"exp\.toml is not UTF-8 text: invalid continuation byte at byte \d+ "
         r"\(line 8\); save it as UTF-8"),
    case("manifest-missing", results_call("arx", lambda d: d, lambda m: m, "rerender-no-manifest"),
         FileFormatError, r"manifest .*manifest\.json: no such file; check the path .*; so the "
         r"inputs of this run cannot be checked"),
    case("manifest-list", results_call("arx", lambda d: d, lambda m: [m], "rerender"),
         FileFormatError, r"manifest .*manifest\.json must be a JSON object, got an array"),
    case("manifest-inputs-object", results_call("arx", lambda d: d, put("inputs", {}), "rerender"),
         FileFormatError, r"inputs must be an array \[\.\.\.\], got an object \{\}"),
    case("manifest-entry-text", results_call("arx", lambda d: d, put("inputs.1", "x.csv"),
                                             "rerender"),
         FileFormatError, r"inputs\[1\] must be an object \{\.\.\.\}, got the string 'x\.csv'"),
    case("manifest-path-number", results_call("arx", lambda d: d, put("inputs.0.path", 1),
                                              "rerender"),
         FileFormatError, r"inputs\[0\]\.path must be a string, got int 1"),
    case("manifest-sha256-short", results_call("arx", lambda d: d, put("inputs.0.sha256", "ab"),
                                               "rerender"),
         FileFormatError, r"inputs\[0\]\.sha256 must be a SHA-256 in lowercase hex \(64 digits\), "
         r"got 'ab'"),
    # the fleet file's records: checked by the record globbing, not the TOML reader -----------
    case("fleet-glob-nul", fleet_call(FLEET.replace("runs/*.toml", "ru\\u0000ns/*.toml")),
         OptionError, r"\[records\] glob.*NUL"),
    case("fleet-glob-long", fleet_call(FLEET.replace("runs/*.toml", "runs/*.toml" * 1000)),
         OptionError, r"\[records\] glob .* is 11000 bytes long; paths stop at 4095"),
    case("fleet-glob-deep", fleet_call(FLEET.replace("runs/*.toml", "r*/" * 500 + "*.toml")),
         OptionError, r"\[records\] glob .* has 501 folder levels; a glob of records goes at "
         r"most 32 deep"),
    case("fleet-manifest-too-long",
         fleet_call(FLEET.replace('glob = "runs/*.toml"', f'manifest = "{LONG_NAME}"')),
         OptionError, r"\[records\] manifest .* has a name of \d+ bytes"),
]


def _freeze_folder(folder: Path) -> None:
    """Remember every file's SHA-256 before the call (compared after it)."""
    _BEFORE[folder] = _hashes(folder)


_BEFORE: dict[Path, dict[str, str]] = {}


def _hashes(folder: Path) -> dict[str, str]:
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
            if p.is_file() else "folder" for p in sorted(folder.rglob("*"))}


@pytest.mark.parametrize(("call", "error", "match"), CASES)
def test_bad_document_raises_the_right_error(call, error, match, tmp_path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # a ServoidWarning on the way to the error is fine
        with pytest.raises(error, match=match) as info:
            call(tmp_path)
    assert type(info.value) is error, f"raised {type(info.value).__name__}: {info.value}"
    assert isinstance(info.value, BUILTIN[error])
    assert len(str(info.value)) < 1000, "the message quotes too much of the value"
    if tmp_path in _BEFORE:
        assert _hashes(tmp_path) == _BEFORE.pop(tmp_path), "the call changed or left files"


def test_a_utf8_byte_order_mark_is_read(tmp_path):
    """The mark some editors write before UTF-8 text is no damage: the documents read."""
    doc = seed("models", "tf-continuous", tmp_path)
    (tmp_path / "model.json").write_bytes(b"\xef\xbb\xbf" + json.dumps(doc).encode())
    assert load_model(tmp_path / "model.json").delay == doc["delay"]
    spec_call(b"\xef\xbb\xbf" + SPEC.encode())(tmp_path)
    (tmp_path / "results.json").write_bytes(
        b"\xef\xbb\xbf" + json.dumps(seed("results", "arx", tmp_path)).encode())
    assert set(load_results(tmp_path / "results.json").models) == {"G"}


def test_catalogue_covers_every_document():
    names = [p.id for p in CASES]
    for prefix in ("model-", "results-", "manifest-", "spec-", "fleet-"):
        assert sum(n.startswith(prefix) for n in names) >= 3, prefix
