"""servoid.plants.ema's public surface: exports, docstrings, doctests, the plant record."""

from __future__ import annotations

import copy
import doctest
import importlib
import inspect
import math
import pkgutil
import warnings

import numpy as np
import pytest

from servoid import ServoidError
from servoid.plants import PARTS, PLANTS, ema

MODULES = sorted(m.name for m in pkgutil.iter_modules(ema.__path__))


def _kind(name):
    return 0 if name.isupper() else 1 if name[0].isupper() else 2


def test_exports_are_sorted_unique_importable_and_documented():
    names = ema.__all__
    assert names == sorted(names, key=lambda n: (_kind(n), n))
    assert len(set(names)) == len(names)
    for name in names:
        obj = getattr(ema, name)
        if inspect.isfunction(obj) or inspect.isclass(obj):
            summary = inspect.getdoc(obj).splitlines()[0]
            assert len(summary) < 64 and summary.endswith("."), (name, summary)


def test_importing_the_plants_loads_no_numerics():
    import subprocess
    import sys

    code = ("import sys, servoid.plants; print(sorted(m for m in ('numpy', 'scipy', 'numba') "
            "if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_the_plant_record_names_every_part_and_each_loads():
    plant = PLANTS["ema"]
    assert plant is ema.PLANT
    # every part but the optional excite limit check (servoid excite --plant: the EHSA's so far)
    assert set(plant.parts) == set(PARTS) - {"limits"}
    assert plant.load("simulate") is ema.simulate_ema
    assert plant.load("parameters")["tvc"] is ema.TVC_EMA
    assert plant.load("loop") is ema.EmaController
    assert plant.load("bench") is ema.write_bench
    assert plant.load("fleet") is ema.write_fleet
    assert plant.load("methods") == (ema.METHOD,)
    assert callable(plant.load("rhs"))
    from servoid.workflows import get_method

    assert get_method("ema") is ema.METHOD


@pytest.mark.parametrize("module", MODULES)
def test_modules_stay_small_and_their_doctests_pass(module):
    mod = importlib.import_module(f"servoid.plants.ema.{module}")
    assert inspect.getsource(mod).count("\n") < 800, module
    result = doctest.testmod(mod, optionflags=doctest.NORMALIZE_WHITESPACE)
    assert result.failed == 0


BAD = {"None": None, "text": "abc", "empty": np.array([]), "list-of-text": ["a", "b"],
       "nan": math.nan}
# output folders: text is a valid value there (they would run the bench into it)
TEXT_IS_VALID = {"write_bench", "write_fleet"}


def _callables():
    for name in ema.__all__:
        obj = getattr(ema, name)
        if not (inspect.isfunction(obj) or inspect.isclass(obj)):
            continue
        needed = [p for p in inspect.signature(obj).parameters.values()
                  if p.default is p.empty and p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD)]
        if needed:
            yield pytest.param(obj, needed, name in TEXT_IS_VALID, id=name)


@pytest.mark.parametrize(("func", "needed", "text_ok"), list(_callables()))
def test_bad_arguments_raise_only_servoid_errors(func, needed, text_ok, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    leaks = []
    for label, bad in BAD.items():
        if text_ok and label == "text":
            continue
        args = [bad for p in needed if p.kind is not p.KEYWORD_ONLY]
        kwargs = {p.name: bad for p in needed if p.kind is p.KEYWORD_ONLY}
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                func(*copy.deepcopy(args), **copy.deepcopy(kwargs))
        except ServoidError:
            pass
        except Exception as exc:  # noqa: BLE001 - the point of the test
            leaks.append(f"{label}: {type(exc).__name__}: {exc}")
    assert not leaks, "\n".join(leaks)
