"""Grammar-aware fuzzing of the document loaders: a result or a ServoidError, nothing else.

The reduced run of ``benchmarks/bench_fuzz.py``'s loader rows (issue 21):
the first inputs of ``loader_inputs.make_input`` for the model file
(:func:`servoid.load_model`), the results folder
(:func:`servoid.load_results`, ``greybox_record``, :func:`rerender` and
its manifest) and the experiment file (:func:`load_experiment_spec`, then
its records and a write/read round trip), in process.  Each input is a
valid document with mutations that follow its grammar (wrong types,
missing and extra keys, edge numbers, deep nesting, odd strings, reshaped
arrays, wrong kinds) and sometimes byte damage; the seed string fixes them,
so a run never flakes and a failure names the input to rebuild.  Any
exception that is not a :class:`~servoid.ServoidError` fails the test.

The counts keep the three tests near 10 s together on the 2-core CI
machine; the long run (tens of thousands of inputs, forked children that
survive a signal) is the benchmark.  The fleet file is fuzzed there only:
its record globbing and manifest paths are checked elsewhere, and the
catalogue (``test_catalogue_documents.py``) holds those classes.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import pytest
from loader_inputs import N_MODES, SEED, make_input, prepare, run_input, seed_input, seed_names

#: Inputs per loader in the suite: 3-5 s each here (the first results and spec inputs import scipy).
COUNTS = {"model": 300, "results": 150, "spec": 250}


@pytest.mark.parametrize("loader", sorted(COUNTS))
def test_loader_fuzz_raises_only_servoid_errors(loader: str, tmp_path: Path) -> None:
    prepare(tmp_path)
    failures, outcomes = [], set()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # damaged models warn (unstable, slow): not the finding
        for index in range(COUNTS[loader]):
            inp = make_input(loader, index, tmp_path)
            try:
                outcomes.add(run_input(inp, tmp_path))
            except Exception as exc:  # noqa: BLE001 - every escape is the finding
                failures.append(f"input {index} (mode {inp.mode}; {'; '.join(inp.ops)}): "
                                f"{type(exc).__name__}: {str(exc)[:300]}")
    assert not failures, (f"{len(failures)} of {COUNTS[loader]} inputs (seed {SEED}) escaped "
                          "as non-servoid errors:\n" + "\n".join(failures[:10]))
    # the inputs reach past the parser: some still load, others fail in the checks
    assert "ok" in outcomes and len(outcomes) >= 2, outcomes


@pytest.mark.parametrize("loader", ["model", "results", "spec", "fleet"])
def test_every_seed_loads(loader: str, tmp_path: Path) -> None:
    """The fuzzers start from valid documents: each seed, unmutated, loads in every mode."""
    prepare(tmp_path)
    for name in seed_names(loader):
        for mode in range(N_MODES[loader]):
            outcome = run_input(seed_input(loader, name, mode, tmp_path), tmp_path)
            expected = _seed_outcome(loader, name, mode)
            assert outcome == expected, f"{loader} seed {name} mode {mode}: {outcome}"


def _seed_outcome(loader: str, name: str, mode: int) -> str:
    """What an unmutated seed gives: "ok", but for the refusals the call mode asks for."""
    if loader == "results" and mode == 3:  # rerender: the fuzzers never write the rig files,
        return "error:MissingFileError"  # so the experiment file the manifest names is missing
    if name.startswith("greybox") and mode == 0:  # a grey-box model without allow_code
        return "error:OptionError"
    return "ok"
