"""Load a function from a user's Python file by its path.

``"my_model.py:rhs"`` names the file (relative to a base folder, the
experiment file's) and the function.  The file is executed as a fresh
module with :mod:`importlib` from its path — nothing is added to
``sys.path``, the module is not registered in ``sys.modules`` and no
``__pycache__`` is written beside it — so its imports are resolved as
usual but it cannot shadow or be shadowed by an installed module.
Executing it runs arbitrary code: the caller decides whether it may (the
workflows ask for ``--allow-code``).  An error raised
while executing it becomes a :class:`~servoid.ModelError` naming the file
and the line.
"""

from __future__ import annotations

import hashlib
import importlib.util
import inspect
from collections.abc import Callable
from pathlib import Path
from types import ModuleType
from typing import Any, NamedTuple

from .._errors import MissingFileError, ModelError, OptionError
from ._ode import user_error

__all__ = ["FunctionRef", "load_function", "parse_ref"]


class FunctionRef(NamedTuple):
    """``(file, function)`` parsed from ``"file.py:function"``."""

    file: str
    function: str


def parse_ref(value: str, key: str) -> FunctionRef:
    """Split ``"file.py:function"`` (``key`` names the option)."""
    text = value.strip()
    file, sep, name = text.rpartition(":")
    if not sep or not file.strip() or not name.strip():
        raise OptionError(f"{key} = {value!r} must name a Python file and a function in it, "
                          "e.g. \"my_model.py:rhs\"")
    if not name.strip().isidentifier():
        raise OptionError(f"{key} = {value!r}: {name.strip()!r} is not a function name")
    if not file.strip().endswith(".py"):
        raise OptionError(f"{key} = {value!r}: the file must be a Python file (.py)")
    return FunctionRef(file.strip(), name.strip())


def load_function(ref: FunctionRef, base: Path, key: str,
                  modules: dict[Path, ModuleType] | None = None) -> tuple[
                      Callable[..., Any], Path]:
    """Execute the file ``ref`` names and return the function.

    Parameters
    ----------
    ref : FunctionRef
        File and function.
    base : Path
        Folder a relative file is taken from.
    key : str
        The option, for messages (``"[identify] model"``).
    modules : dict, optional
        Files already executed in this run (path → module), so that the
        model and output functions of one file share one module.

    Returns
    -------
    (callable, Path)
        The function and the resolved file.

    Raises
    ------
    MissingFileError
        No such file.
    ModelError
        The file fails to execute (naming the line).
    OptionError
        The file has no function of that name (the message lists those it has).
    """
    path = (base / ref.file).resolve()
    if not path.is_file():
        raise MissingFileError(f"{key} = \"{ref.file}:{ref.function}\": no file {path} (the "
                               "path is taken from the experiment file's folder)")
    cache = {} if modules is None else modules
    module = cache.get(path)
    if module is None:
        module = _execute(path)
        cache[path] = module
    fn = getattr(module, ref.function, None)
    if fn is None or not callable(fn):
        defined = sorted(n for n, v in vars(module).items()
                         if inspect.isfunction(v) and v.__module__ == module.__name__)
        raise OptionError(f"{key} = \"{ref.file}:{ref.function}\": {path.name} has no function "
                          f"{ref.function!r}; it defines "
                          f"{', '.join(defined) if defined else 'no functions'}")
    return fn, path


def _execute(path: Path) -> ModuleType:
    digest = hashlib.sha256(str(path).encode()).hexdigest()[:12]
    name = f"servoid_user_model_{digest}"  # private: never the name of an installed module
    spec = importlib.util.spec_from_file_location(name, path)
    if spec is None:
        raise ModelError(f"{path} cannot be loaded as a Python module")
    module = importlib.util.module_from_spec(spec)
    try:
        # compiled from its text, not through the import system's loader, which would write
        # a __pycache__ folder beside the user's file
        code = compile(path.read_bytes(), str(path), "exec")
        exec(code, module.__dict__)  # noqa: S102 — the caller was allowed to run this file
    except Exception as exc:  # noqa: BLE001 — user code may raise anything
        raise user_error(exc, path.name, path) from None
    return module
