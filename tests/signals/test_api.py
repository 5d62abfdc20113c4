"""Public surface of servoid.signals: exports, docstrings, doctests."""

from __future__ import annotations

import doctest
import importlib
import inspect
import re

import pytest

from servoid import signals

EXPECTED = [
    "PRBS_TAPS",
    "AmplitudeRule",
    "ChirpMethod",
    "CrestMethod",
    "Excitation",
    "ExcitationRole",
    "Harmonics",
    "Limit",
    "LineGrid",
    "LineSet",
    "MultisinePlan",
    "MultisineScale",
    "Phases",
    "Spectrum",
    "SpectrumMethod",
    "chirp",
    "crest_factor",
    "largest_amplitude",
    "multisine",
    "plan_multisine",
    "power_spectrum",
    "prbs",
    "prbs_clock",
    "prbs_length",
    "prbs_register_for",
    "random_binary",
    "random_multisine",
    "read_plan",
    "steps",
]
MODULES = ["_binary", "_checks", "_excitation", "_lfsr", "_multisine_design", "_spectrum",
           "_waveforms"]
MODULES = ["_binary", "_checks", "_excitation", "_lfsr", "_limits", "_spectrum", "_waveforms"]


def _isort_key(name: str) -> tuple[int, str]:
    # the project's order (as in servoid.data): CONSTANTS, then Classes, then functions
    kind = 0 if name.isupper() else 1 if name[0].isupper() else 2
    return kind, name


def test_exports_are_pinned_and_sorted() -> None:
    assert set(signals.__all__) == set(EXPECTED)  # a public name is removed only on purpose
    assert sorted(signals.__all__, key=_isort_key) == signals.__all__
    for name in EXPECTED:
        assert hasattr(signals, name)


def _documented() -> list[tuple[str, object]]:
    items = []
    for name in EXPECTED:
        obj = getattr(signals, name)
        if inspect.isfunction(obj) or inspect.isclass(obj):
            items.append((name, obj))
    items.append(("Excitation.to_experiment", signals.Excitation.to_experiment))
    return items


@pytest.mark.parametrize(("name", "obj"), _documented(), ids=[n for n, _ in _documented()])
def test_docstring_summary_and_parameters(name: str, obj: object) -> None:
    doc = inspect.getdoc(obj)
    assert doc, f"{name} has no docstring"
    summary = doc.splitlines()[0]
    assert len(summary) < 64 and summary.endswith("."), summary
    params = [p for p in inspect.signature(obj).parameters if p != "self"]  # type: ignore[arg-type]
    if not params:
        return
    assert "Parameters\n----------" in doc, f"{name} has no Parameters section"
    section = doc.split("Parameters\n----------", 1)[1]
    section = re.split(r"\n(Returns|Raises|Examples|Notes)\n-+", section)[0]
    listed = set()
    for line in section.splitlines():
        match = re.match(r"^(\w+(?:, \w+)*) :", line)
        if match:
            listed.update(match.group(1).split(", "))
    missing = [p for p in params if p not in listed]
    assert not missing, f"{name}: undocumented parameters {missing}"


@pytest.mark.parametrize("module", MODULES)
def test_doctests(module: str) -> None:
    mod = importlib.import_module(f"servoid.signals.{module}")
    result = doctest.testmod(mod, optionflags=doctest.NORMALIZE_WHITESPACE)
    assert result.failed == 0


def test_modules_stay_small() -> None:
    for module in MODULES:
        source = inspect.getsource(importlib.import_module(f"servoid.signals.{module}"))
        assert source.count("\n") < 800, module
