"""Every registered method, checked the same way: a method is checked by being registered.

Like scikit-learn's ``parametrize_with_checks`` over its estimators, each
check below runs over :func:`servoid.workflows.method_names`, each method on
the small record its :attr:`~servoid.workflows.Method.example` writes:

* it runs from the experiment file through the API and from the command
  line with ``--json`` (the same numbers), and as a row of a two-record
  fleet (``--workers 1``) whose parameters are its summary's;
* its result keeps the contract (``summary``, ``models``, ``verdict``,
  ``sections``, ``page``, ``figures``, ``inputs``, ``to_dict``) and its
  ``results.json`` holds what ``summary()`` and ``verdict()`` say;
* its results round-trip through :func:`~servoid.workflows.load_results`
  (parameters equal to the last bit, the models it rebuilds among the
  result's own);
* its report renders with the verdict box;
* an unknown ``[identify]`` key, a wrong option type and an unknown key in
  a table of its own keys (``[loop]``) are refused, naming the key.

The records are small (each method runs in about a second), and each is
made and identified once per module, so the whole suite stays short.
"""

from __future__ import annotations

import contextlib
import csv
import dataclasses
import io
import json
import math
import warnings
from pathlib import Path
from types import MappingProxyType
from typing import Any

import pytest

from servoid import ServoidError
from servoid.cli import main
from servoid.data import load_experiment_spec
from servoid.fleet import run_fleet
from servoid.report import Page, Section, Verdict, to_jsonable
from servoid.workflows import (
    Identification,
    get_method,
    identify,
    load_results,
    method_names,
)
from servoid.workflows._registry import CONTRACT
from servoid.workflows._summary import RecordSummary

NAMES = method_names()


@dataclasses.dataclass
class Run:
    """One method on its example: the API result, the command line's output and folder."""

    name: str
    experiment: Path
    result: Any
    payload: dict[str, Any]
    folder: Path


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Run]:
    return {}


@pytest.fixture
def run(runs: dict[str, Run], tmp_path_factory: pytest.TempPathFactory,
        request: pytest.FixtureRequest) -> Run:
    """The method's example, identified by the API (computing) and the CLI (writing), once."""
    name = request.node.callspec.params["name"]
    if name not in runs:
        method = get_method(name)
        folder = tmp_path_factory.mktemp(f"conformance-{name}")
        experiment = method.example(folder / "unit0", 0)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # a method's notes are warned too: not checked here
            result = identify(experiment, write=False, allow_code=method.runs_code)
        out = folder / "results"
        words = ["identify", str(experiment), "--out", str(out), "--json"]
        stdout = io.StringIO()
        with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(io.StringIO()):
            code = main([*words, "--allow-code"] if method.runs_code else words)
        payload = json.loads(stdout.getvalue())
        assert code == 0, payload
        runs[name] = Run(name, experiment, result, payload, out)
    return runs[name]


def _same(a: Any, b: Any) -> bool:
    """Equal as results.json writes them (NaN and infinities as null)."""
    return to_jsonable(a) == to_jsonable(b)


# -- registration -----------------------------------------------------------------------------


@pytest.mark.parametrize("name", NAMES)
def test_a_registered_method_declares_what_the_suite_needs(name):
    method = get_method(name)
    assert callable(method.example), f"{name}: a registered method names its example record"
    text = method.describe()
    for schema in method.schemas.values():
        assert f"[{schema.name}] keys" in text
        assert all(o.name in text and o.help for o in schema.options)
    json.dumps(method.to_dict())  # plain data, as servoid methods --json prints it


# -- runs -------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", NAMES)
def test_it_runs_from_toml_and_keeps_the_result_contract(name, run):
    result = run.result
    assert isinstance(result, Identification)
    assert all(callable(getattr(result, a, None)) for a in CONTRACT)
    summary = result.summary()
    assert isinstance(summary, RecordSummary) and summary.method == name
    assert summary.parameters, "a method reports at least one scalar"
    assert len(set(summary.names())) == len(summary.parameters)
    for p in summary.parameters:
        assert isinstance(p.value, float) and isinstance(p.unit, str)
        # an interval holds its value, or there is none (a spec number read from the data)
        assert math.isnan(p.ci_low) or p.ci_low <= p.value <= p.ci_high, p
    verdict = result.verdict()
    assert isinstance(verdict, Verdict)
    assert summary.decision == verdict.decision and summary.reason == verdict.reason
    data = result.to_dict()
    assert data["method"] == name
    assert _same(data["summary"], summary.to_dict())
    assert _same(data["verdict"], verdict.to_dict())
    models = result.models()
    assert all(isinstance(k, str) and v is not None for k, v in models.items())


@pytest.mark.parametrize("name", NAMES)
def test_the_command_line_gives_the_same_numbers(name, run):
    payload = run.payload
    assert payload["ok"] and payload["method"] == name
    assert _same(payload["summary"]["parameters"],
                 [p.to_dict() for p in run.result.summary().parameters])
    written = {Path(f).name for f in payload["files"]}
    assert {"results.json", "report.html", "manifest.json"} <= written


@pytest.mark.parametrize("name", NAMES)
def test_its_results_round_trip_through_load_results(name, run):
    method = get_method(name)
    loaded = load_results(run.folder / "results.json", allow_code=method.runs_code)
    assert _same(loaded.summary.to_dict(), run.payload["summary"])
    own = run.result.models()
    for key, model in loaded.models.items():  # what the file rebuilds is the result's own
        assert key in own and type(model) is type(own[key]), key


@pytest.mark.parametrize("name", NAMES)
def test_its_report_renders_with_the_verdict_box(name, run):
    html = (run.folder / "report.html").read_text(encoding="utf-8")
    decision = run.payload["summary"]["decision"]
    assert f'<div class="box {decision}">' in html
    assert f"{decision.upper()} — " in html
    files = {p.name: p for p in run.folder.iterdir()}
    page = run.result.page(files)
    sections = run.result.sections(files)
    assert isinstance(page, Page) and all(isinstance(s, Section) for s in sections)
    assert tuple(s.title for s in sections) == tuple(s.title for s in page.sections)
    assert all(s.title.split(":")[0] in html for s in sections)
    assert set(run.result.figures()) <= set(files)


@pytest.mark.parametrize("name", NAMES)
def test_it_works_as_a_fleet_row(name, run, tmp_path):
    method = get_method(name)
    second = method.example(run.experiment.parent.parent / "unit1", 1)
    manifest = tmp_path / "units.csv"
    with open(manifest, "w", newline="", encoding="utf-8") as fh:
        writer = csv.writer(fh)
        writer.writerow(["path", "serial"])
        writer.writerows([[run.experiment, "U0"], [second, "U1"]])
    fleet_file = tmp_path / "fleet.toml"
    fleet_file.write_text(f'[records]\nmanifest = "{manifest.name}"\n', encoding="utf-8")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fleet = run_fleet(fleet_file, tmp_path / "out", workers=1, progress=False,
                          allow_code=method.runs_code)
    assert [r["status"] for r in fleet.rows] == ["ok", "ok"], [r["error"] for r in fleet.rows]
    assert [r["method"] for r in fleet.rows] == [name, name]
    names = run.result.summary().names()
    assert tuple(p.name for p in fleet.parameters) == names  # its own scalars, trended
    row = fleet.rows[0]
    for p in run.result.summary().parameters:
        assert _same(row[p.name], p.value), p.name
    assert (tmp_path / "out" / "report.html").is_file()


# -- refusals ---------------------------------------------------------------------------------


@pytest.mark.parametrize("name", NAMES)
def test_an_unknown_identify_key_is_refused_naming_it(name, run):
    spec = load_experiment_spec(run.experiment)
    bad = dataclasses.replace(spec, identify=MappingProxyType({**spec.identify,
                                                               "no_such_key": 1}))
    with pytest.raises(ServoidError, match=r"no_such_key.*valid keys"):
        identify(bad, write=False, allow_code=get_method(name).runs_code)


@pytest.mark.parametrize("name", NAMES)
def test_a_wrong_option_type_is_refused_naming_the_key(name, run):
    method = get_method(name)
    option = next(o for o in method.options if isinstance(o.default, (bool, int, float, str)))
    wrong = 12345 if isinstance(option.default, str) else "not a number"
    spec = load_experiment_spec(run.experiment)
    bad = dataclasses.replace(spec, identify=MappingProxyType({**spec.identify,
                                                               option.name: wrong}))
    with pytest.raises(ServoidError, match=rf"\[identify\] {option.name}\b"):
        identify(bad, write=False, allow_code=method.runs_code)


@pytest.mark.parametrize("name", NAMES)
def test_an_unknown_key_in_a_table_it_reads_is_refused(name, run):
    method = get_method(name)
    spec = load_experiment_spec(run.experiment)
    options = method.parse(spec.identify)
    for table, schema in method.schemas.items():
        given = {**getattr(spec, table), "no_such_key": 1}
        if not schema.reads(options, given):
            continue  # not read with these options: left as the rig describes it
        bad = dataclasses.replace(spec, **{table: MappingProxyType(given)})
        with pytest.raises(ServoidError, match=rf"unknown key\(s\) in \[{table}\]: no_such_key; "
                                               rf"valid keys are {schema.keys[0]}"):
            identify(bad, write=False, allow_code=method.runs_code)
