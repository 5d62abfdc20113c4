"""Hypothesis fuzzers of the rig-file readers: a ServoidError or a result, nothing else.

Two kinds of input: valid seed files with byte-level mutations
(``fuzz_inputs.py``), and files built from each format's grammar with one
planted fault in a field that matters (``fuzz_grammar.py``: CSV dialects,
TDMS segments, MAT v5 tags, HDF5 attributes, datasets and links). Each is
read in process: the reader must return an Experiment (or, for TOML, a
spec) or raise a :class:`ServoidError`; any other exception fails the test
(a crash ends the session, loudly). ``derandomize=True`` and no example
database make every run draw the same inputs, so CI never flakes, and there
is no per-example deadline to trip on a loaded machine; the example counts
keep each test within about 10 s on the 2-core CI machine (a v7.3 read
forks a child, about 80 ms here: fewer v7.3 examples). The long run (each
reader in forked batches that survive a signal) is
``benchmarks/bench_fuzz.py``.
"""

from __future__ import annotations

import logging
import random
from collections.abc import Iterator
from pathlib import Path

import pytest
from fuzz_grammar import GRAMMARS, grammar_input, read_grammar
from fuzz_inputs import FORMATS, N_MODES, N_OPS, mutate, own_seeds, read_input, seeds
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

#: Examples per format: each test stays near 10 s (MAT v5 and v7.3 are the slow ones).
EXAMPLES = {"csv": 800, "toml": 800, "tdms": 600, "mat4": 700, "mat5": 600, "mat5z": 500,
            "mat73": 120}
#: Grammar-built files per format, each test near 10 s.
GRAMMAR_EXAMPLES = {"csv": 600, "tdms": 600, "mat5": 500, "mat73": 100}

_OPS = st.lists(
    st.tuples(st.integers(0, N_OPS - 1), st.integers(0, 2**32 - 1), st.integers(0, 2**64 - 1)),
    min_size=1,
    max_size=3,
)


@pytest.fixture(scope="module")
def scratch(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("fuzz")


@pytest.fixture(autouse=True)
def _quiet_nptdms() -> Iterator[None]:
    """Damaged files make npTDMS log; that is not the finding here."""
    logger = logging.getLogger("nptdms")
    propagate, logger.propagate = logger.propagate, False
    yield
    logger.propagate = propagate


def _fuzz(fmt: str) -> object:
    @settings(max_examples=EXAMPLES[fmt], derandomize=True, database=None, deadline=None,
              suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
    @given(seed=st.integers(0, len(seeds(fmt)) - 1), ops=_OPS, mode=st.integers(0, N_MODES - 1))
    def run(scratch: Path, seed: int, ops: list[tuple[int, int, int]], mode: int) -> None:
        outcome = read_input(fmt, mutate(fmt, seeds(fmt)[seed], ops), mode, scratch)
        assert outcome == "ok" or outcome.startswith("error:")

    return run


@pytest.mark.filterwarnings("ignore")  # scipy and h5py warn about damaged files
@pytest.mark.parametrize("fmt", FORMATS)
def test_reader_fuzz(fmt: str, scratch: Path) -> None:
    _fuzz(fmt)(scratch)  # type: ignore[operator]


@pytest.mark.filterwarnings("ignore")
@pytest.mark.parametrize("fmt", sorted(GRAMMARS))
def test_reader_grammar_fuzz(fmt: str, scratch: Path) -> None:
    @settings(max_examples=GRAMMAR_EXAMPLES[fmt], derandomize=True, database=None,
              deadline=None, suppress_health_check=[HealthCheck.too_slow,
                                                    HealthCheck.function_scoped_fixture])
    @given(key=st.integers(0, 2**32 - 1))
    def run(key: int) -> None:
        data, kwargs = grammar_input(fmt, random.Random(f"grammar:{fmt}:{key}"))
        outcome = read_grammar(fmt, data, kwargs, scratch)
        assert outcome == "ok" or outcome.startswith("error:")

    run()


@pytest.mark.parametrize("fmt", sorted(GRAMMARS))
def test_grammar_files_without_a_fault_read(fmt: str, scratch: Path) -> None:
    """Files built without a planted fault read cleanly: the grammar is the format's."""
    outcomes = [read_grammar(fmt, *grammar_input(fmt, random.Random(f"valid:{fmt}:{key}"),
                                                 faults=False), scratch)
                for key in range(40)]
    assert outcomes == ["ok"] * 40


@pytest.mark.parametrize("fmt", FORMATS)
def test_seeds_are_valid(fmt: str, scratch: Path) -> None:
    """servoid's own seeds read cleanly, so the fuzzers start from valid files.

    A seed of a logger's file (a preamble, several TDMS groups) reads in the
    call mode with the rig-file options only.
    """
    for k, data in enumerate(own_seeds(fmt)):
        outcomes = [read_input(fmt, data, mode, scratch) for mode in range(N_MODES)]
        assert "ok" in outcomes, f"{fmt} seed {k}: {outcomes}"
