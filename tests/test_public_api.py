"""The curated public surface: exports pinned, every export documented."""

from __future__ import annotations

import importlib
import inspect

import pytest

PACKAGES = ["servoid", "servoid.data", "servoid.signals", "servoid.models", "servoid.estimate",
            "servoid.validate", "servoid.report", "servoid.workflows", "servoid.cli",
            "servoid.actuators", "servoid.closedloop", "servoid.bench", "servoid.datasets",
            "servoid.multistep"]


def test_top_level_exports():
    import servoid

    assert servoid.__all__ == sorted(servoid.__all__, key=str.lower) or servoid.__all__ == sorted(
        servoid.__all__
    )
    assert {"Experiment", "ExperimentSet", "ServoidError", "DataError", "__version__"} <= set(
        servoid.__all__
    )


@pytest.mark.parametrize("name", PACKAGES)
def test_all_names_exist_and_are_documented(name):
    module = importlib.import_module(name)
    assert module.__doc__, f"{name} has no module docstring"
    for export in module.__all__:
        obj = getattr(module, export)
        if inspect.isfunction(obj) or inspect.isclass(obj):
            doc = inspect.getdoc(obj)
            assert doc, f"{name}.{export} has no docstring"
            summary = doc.splitlines()[0]
            assert len(summary) < 80, f"{name}.{export}: summary too long: {summary!r}"


def test_error_tree():
    import servoid

    assert issubclass(servoid.DataError, ValueError)
    assert issubclass(servoid.FileFormatError, servoid.DataError)
    assert issubclass(servoid.ChannelError, KeyError)
    assert issubclass(servoid.ConvergenceError, RuntimeError)
    assert issubclass(servoid.OutputExistsError, FileExistsError)
    assert issubclass(servoid.OptionTypeError, TypeError)
    for cls in (servoid.DataError, servoid.OptionError, servoid.OptionTypeError,
                servoid.ModelError):
        assert issubclass(cls, servoid.ServoidError)
