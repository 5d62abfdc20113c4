"""``servoid bench``: rehearse a test on a virtual rig, each plant with its own commands."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from typing import Any

__all__ = ["add_bench"]


def add_bench(commands: Any, json_flag: Callable[[argparse.ArgumentParser], None]) -> None:
    """Add ``bench`` with every plant's rig commands (its optional ``cli`` part)."""
    from ..plants import PLANTS  # the records only: each part loads when it is used

    bench = commands.add_parser(
        "bench", help="rehearse a test on a virtual rig and write its files",
        description="Run a designed excitation on a virtual test rig (actuator in its loop, "
        "sensors, noise, anti-alias filter, ADC) and write what a real rig writes: the rig "
        "file in volts, the experiment TOML and truth.json.",
    )
    rigs = bench.add_subparsers(title="rigs", metavar="RIG", required=True)
    for plant in PLANTS.values():  # argparse only: the benches load when a command runs
        if "cli" in plant.parts:
            plant.load("cli")(rigs, json_flag)
