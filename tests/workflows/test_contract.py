"""The registry owns the tables and the results: schemas, properties instead of names, one hash."""

from __future__ import annotations

import ast
import collections
import dataclasses
import json
import os
import subprocess
import sys
import textwrap
import warnings
from pathlib import Path
from types import MappingProxyType

import pytest

import servoid.workflows._common as common
from servoid import OptionError
from servoid.cli import main
from servoid.data import load_experiment_spec
from servoid.workflows import Method, Option, get_method, identify, method_names, rerender
from servoid.workflows._registry import TableSchema

SRC = Path(__file__).parents[2] / "src" / "servoid"


@pytest.fixture
def counted(monkeypatch):
    """Count every SHA-256 of a whole file, by real path.

    Every such hash of the workflows is ``_common.sha256``, which opens the
    file; its ``open`` is counted, however a module imported the function.
    """
    counts: collections.Counter[str] = collections.Counter()

    def counting_open(path, *args, **kwargs):
        counts[os.path.realpath(path)] += 1
        return open(path, *args, **kwargs)

    monkeypatch.setattr(common, "open", counting_open, raising=False)
    return counts


def _arx_with_truth(folder):
    experiment = get_method("arx").example(folder, 0)
    (folder / "truth.json").write_text('{"seed": 0, "a1": -1.2}\n', encoding="utf-8")
    text = experiment.read_text(encoding="utf-8")
    experiment.write_text(text + '\n[report]\ntruth = "truth.json"\n', encoding="utf-8")
    return experiment


def test_each_input_is_hashed_once_per_run(tmp_path, counted):
    experiment = _arx_with_truth(tmp_path)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = identify(experiment, tmp_path / "out")
    inputs = [os.path.realpath(p) for p in result.inputs()]
    assert len(inputs) == 3  # the record, the experiment file, the truth
    # results.json (its data_sha256 and data_files), the page, the provenance and the
    # manifest all read the one digest of each input
    assert {p: counted[p] for p in inputs} == dict.fromkeys(inputs, 1)
    manifest = json.loads((tmp_path / "out" / "manifest.json").read_text(encoding="utf-8"))
    assert {e["path"]: e["sha256"] for e in manifest["inputs"]} == {
        os.path.realpath(p): result.digest(p) for p in result.inputs()}


def test_a_rerender_hashes_each_input_once(tmp_path, counted):
    experiment = _arx_with_truth(tmp_path)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        identify(experiment, tmp_path / "experiment-results")
        counted.clear()
        result = rerender(tmp_path / "experiment-results" / "results.json")
    inputs = [os.path.realpath(p) for p in result.inputs()]
    # checked against the manifest once (the experiment file: on the very bytes parsed)
    assert all(counted[p] <= 1 for p in inputs), {p: counted[p] for p in inputs}


def test_loop_schemas_show_in_servoid_methods(capsys):
    assert main(["methods", "closedloop"]) == 0
    text = capsys.readouterr().out
    assert "[loop] keys (the known loop H = c·G0/(1 + F·G0)):" in text
    assert "  c  forward gain of the loop (required) (default none)" in text
    assert main(["methods", "tf", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert [o["name"] for o in data["table_keys"]["loop"]["options"]] == ["controller",
                                                                          "feedback"]
    assert data["table_keys"]["loop"]["read_when"].startswith('instrument = "r"')


def test_a_table_is_checked_only_when_the_run_reads_it(tmp_path):
    method = get_method("tf")
    spec = load_experiment_spec(method.example(tmp_path, 0))
    ehsa_loop = MappingProxyType({"c": 0.01, "F": 0.01})  # a rig's [loop], not tf's keys
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        identify(dataclasses.replace(spec, loop=ehsa_loop), write=False)  # not read: left as is
    read = dataclasses.replace(
        spec, loop=MappingProxyType({"controller": 0.5, "gain": 1.0}),
        identify=MappingProxyType({**spec.identify, "instrument": "r"}))
    with pytest.raises(OptionError, match=r"unknown key\(s\) in \[loop\]: gain; valid keys are "
                                          r"controller, feedback \(method = \"tf\" reads"):
        identify(read, write=False)


def test_a_schema_refuses_and_fills():
    schema = TableSchema("loop", (Option("k", 2.0, lambda v, w, n: float(v), "a gain"),))
    assert schema.parse({}) == {"k": 2.0} and schema.parse({"k": 3}) == {"k": 3.0}
    with pytest.raises(OptionError, match=r"unknown key\(s\) in \[loop\]: x; valid keys are k"):
        schema.parse({"x": 1}, "demo")
    method = Method("demo", "a test", (), lambda s, o, t: None, tables=(schema, "validation"))
    assert method.tables == ("loop", "validation") and method.schemas["loop"] is schema
    assert method.parse_tables({"loop": {"k": 1}}, {}) == {"[loop]": {"k": 1.0}}
    assert "[loop] keys (a gain" not in method.describe() and "  k  a gain" in method.describe()


def test_no_method_name_in_the_runner_the_results_or_the_fleet():
    """What differs between methods is a property the Method declares, never its name."""
    files = [SRC / "workflows" / "_run.py", SRC / "workflows" / "_results.py",
             SRC / "workflows" / "_summary.py", SRC / "workflows" / "_provenance.py",
             *sorted((SRC / "fleet").glob("*.py"))]
    # a model record's "type" in results.json is a model's name ("narx": a NarxModel), which
    # load_results dispatches on to rebuild the model; a method's name is what may not appear
    model_types = {"_results.py": {"narx"}}
    for file in files:
        names = set(method_names()) - model_types.get(file.name, set())
        tree = ast.parse(file.read_text(encoding="utf-8"))
        found = {node.value for node in ast.walk(tree)
                 if isinstance(node, ast.Constant) and node.value in names}
        assert not found, f"{file.name} names {found}"


def test_an_arx_run_loads_only_what_arx_needs():
    code = textwrap.dedent("""
        import sys, tempfile, warnings
        from pathlib import Path
        from servoid.workflows import get_method, identify
        warnings.simplefilter("ignore")
        with tempfile.TemporaryDirectory() as tmp:
            identify(get_method("arx").example(Path(tmp), 0), Path(tmp) / "out")
        print(sorted(m for m in sys.modules if m.startswith("servoid.")))
    """)
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=300, check=True)
    loaded = set(eval(done.stdout.strip().splitlines()[-1]))  # noqa: S307 — printed above
    others = {f"servoid.workflows.{m}" for m in ("_pem", "_tf", "_n4sid", "_frf", "_narx",
                                                "_blocks", "_greybox", "_closedloop_any")}
    plants = {f"servoid.plants.{p}.{m}" for p in ("ehsa", "pneumatic", "rigid", "ema")
              for m in ("_workflow", "_workflow_run")}
    assert "servoid.workflows._arx" in loaded
    assert not loaded & (others | plants | {"servoid.fleet", "servoid.nonlinear"})
