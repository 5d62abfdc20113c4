"""Names that moved into servoid.plants still work from their old paths, with a warning."""

from __future__ import annotations

import importlib
import inspect
import warnings

import pytest

from servoid import plants

#: old package → every name it exported before the actuators moved into servoid.plants
OLD = {
    "servoid.actuators": importlib.import_module("servoid.actuators")._MOVED,
    "servoid.multistep": importlib.import_module("servoid.multistep")._MOVED,
    "servoid.closedloop": importlib.import_module("servoid.closedloop")._MOVED,
    "servoid.bench": importlib.import_module("servoid.bench")._MOVED,
    "servoid.estimate": importlib.import_module("servoid.estimate")._MOVED,
    "servoid.workflows": importlib.import_module("servoid.workflows")._MOVED,
}
CASES = [(old, name, new) for old, table in OLD.items() for name, new in sorted(table.items())]


@pytest.mark.parametrize(("old", "name", "new"), CASES, ids=[f"{o}.{n}" for o, n, _ in CASES])
def test_an_old_path_gives_the_new_object_and_names_it(old, name, new):
    module = importlib.import_module(old)
    with pytest.warns(DeprecationWarning, match=rf"{old}\.{name} moved to {new}\.{name}") as seen:
        value = getattr(module, name)
    assert value is getattr(importlib.import_module(new), name)
    assert seen[0].filename == __file__  # the caller's line, not servoid's
    assert name in importlib.import_module(new).__all__
    assert name not in module.__all__  # the old surface no longer advertises it


def test_the_old_packages_count_what_moved():
    # every public name of servoid.actuators and servoid.multistep moved; the any-plant
    # closed-loop methods and the generic LTI bench stayed
    assert len(OLD["servoid.actuators"]) == 40 and len(OLD["servoid.multistep"]) == 23
    assert importlib.import_module("servoid.actuators").__all__ == []
    assert set(importlib.import_module("servoid.closedloop").__all__) == {
        "FeedbackTest", "feedback_test", "fit_cliv", "fit_direct_bj", "fit_indirect_tf",
        "fit_two_stage", "warn_if_feedback"}


def test_an_unknown_name_is_an_attribute_error():
    import servoid.actuators

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(AttributeError, match="has no attribute 'nothing'"):
            servoid.actuators.nothing  # noqa: B018


def test_the_friction_laws_are_documented():
    for name in ("coulomb_friction", "karnopp_friction", "stribeck_friction",
                 "three_regime_friction", "viscous_friction"):
        func = getattr(plants, name)
        doc = inspect.getdoc(func) or ""
        assert doc.splitlines()[0].endswith(".") and len(doc.splitlines()[0]) < 64
        for param in inspect.signature(func).parameters:
            assert f"{param} :" in doc or f", {param}" in doc, (name, param)
