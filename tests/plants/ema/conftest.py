"""Shared EMA bench records for the tests (built once per session)."""

from __future__ import annotations

import pytest


@pytest.fixture(scope="session")
def bench_folder(tmp_path_factory):
    """The default bench test written once: ema.tdms, ema.toml, truth.json."""
    from servoid.plants.ema import write_bench

    folder = tmp_path_factory.mktemp("ema-bench")
    write_bench(folder, seed=0)
    return folder
