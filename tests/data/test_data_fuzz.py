"""Hypothesis fuzzers of the rig-file readers: a ServoidError or a result, nothing else.

Each test mutates valid seed files (``fuzz_inputs.py``) and reads them in
process: the reader must return an Experiment (or, for TOML, a spec) or
raise a :class:`ServoidError`; any other exception fails the test (a crash
ends the session, loudly). ``derandomize=True`` and no example database
make every run draw the same inputs, so CI never flakes, and there is no
per-example deadline to trip on a loaded machine; the example counts keep
each test within about 10 s on the 2-core CI machine. The long run (55 000 inputs, each reader in forked
batches that survive a signal) is ``benchmarks/bench_fuzz.py``.
"""

from __future__ import annotations

import logging
from collections.abc import Iterator
from pathlib import Path

import pytest
from fuzz_inputs import FORMATS, N_MODES, N_OPS, mutate, own_seeds, read_input, seeds
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

#: Examples per format: each test stays near 10 s (MAT v5 and v7.3 are the slow ones).
EXAMPLES = {"csv": 800, "toml": 800, "tdms": 600, "mat4": 700, "mat5": 600, "mat5z": 500,
            "mat73": 350}

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


@pytest.mark.parametrize("fmt", FORMATS)
def test_seeds_are_valid(fmt: str, scratch: Path) -> None:
    """servoid's own seeds read cleanly, so the fuzzers start from valid files.

    A seed of a logger's file (a preamble, several TDMS groups) reads in the
    call mode with the rig-file options only.
    """
    for k, data in enumerate(own_seeds(fmt)):
        outcomes = [read_input(fmt, data, mode, scratch) for mode in range(N_MODES)]
        assert "ok" in outcomes, f"{fmt} seed {k}: {outcomes}"
