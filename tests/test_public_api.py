"""The curated public surface: exports pinned, every export documented."""

from __future__ import annotations

import importlib
import inspect

import pytest

import servoid

PACKAGES = ["servoid", "servoid.data", "servoid.signals", "servoid.models", "servoid.estimate",
            "servoid.validate", "servoid.report", "servoid.workflows", "servoid.cli",
            "servoid.closedloop", "servoid.bench", "servoid.datasets",
            "servoid.nonlinear", "servoid.integrate", "servoid.frequency", "servoid.plants", "servoid.plants.ehsa",
            "servoid.plants.pneumatic", "servoid.plants.rigid", "servoid.plants.ema"]


def _isort_key(name: str) -> tuple[int, str]:
    # the project's order (ruff RUF022): CONSTANTS, then Classes, then functions
    kind = 0 if name.isupper() or name.startswith("__") else 1 if name[0].isupper() else 2
    return kind, name


# A verbatim copy of each __all__ pins nothing useful (every change edits both); what is
# pinned instead is the shape: sorted, unique, importable and documented.
@pytest.mark.parametrize("name", PACKAGES)
def test_exports_are_sorted_unique_and_importable(name):
    module = importlib.import_module(name)
    exports = module.__all__
    assert len(set(exports)) == len(exports), f"{name}.__all__ repeats a name"
    assert exports in (sorted(exports), sorted(exports, key=_isort_key)), f"{name}: not sorted"
    for export in exports:
        assert hasattr(module, export), f"{name}.__all__ names {export}, which is missing"


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
            assert len(summary) < 64, f"{name}.{export}: summary too long: {summary!r}"  # STYLE §5
            assert summary.endswith("."), f"{name}.{export}: summary must end with a period"


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


def test_version_is_the_one_pyproject_states():
    import tomllib
    from pathlib import Path

    pyproject = Path(__file__).resolve().parents[1] / "pyproject.toml"
    declared = tomllib.loads(pyproject.read_text(encoding="utf-8"))["project"]["version"]
    assert servoid.__version__ == declared
