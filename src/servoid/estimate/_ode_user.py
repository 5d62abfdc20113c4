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
and the line; so does ``sys.exit()`` (``SystemExit``), which would otherwise
end servoid with the user's exit code and no results.  ``os._exit()`` ends
the process without any Python code running after it, so it cannot be
caught: the command dies with that exit code and writes nothing (a results
folder keeps no partial file, and its stale lock is taken over by the next
run).  Ctrl-C (``KeyboardInterrupt``) stays an interruption.

A fitted model that is saved keeps a reference to this code, not the code:
the file's path, its SHA-256 and the function names (:func:`code_ref`).
:func:`load_recorded` executes the file again only after checking that its
bytes still have that SHA-256, and executes exactly the bytes it checked.
"""

from __future__ import annotations

import hashlib
import importlib.util
import inspect
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from types import ModuleType
from typing import Any, NamedTuple

from .._errors import MissingFileError, ModelError, OptionError
from ._ode import user_error

__all__ = ["FunctionRef", "code_ref", "executed_sha256", "file_sha256", "load_function",
           "load_recorded", "parse_ref"]

#: module global holding the SHA-256 of the bytes a user's file was executed from
_DIGEST = "__servoid_sha256__"


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
                  modules: dict[Path, ModuleType] | None = None,
                  expected: Mapping[str, str] | None = None) -> tuple[
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
    expected : mapping, optional
        Resolved file path → the SHA-256 its bytes must have (a re-render
        of a recorded run; a file not in it is refused): the file is read
        once, and the bytes that were hashed are the bytes executed.

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
        text = path.read_bytes()
        if expected is not None:
            digest = expected.get(str(path))
            now = hashlib.sha256(text).hexdigest()
            if digest is None or now != digest:
                fitted = f"SHA-256 {digest}, now {now}" if digest else "the run recorded no " \
                    "such file"
                raise ModelError(
                    f"{key} = \"{ref.file}:{ref.function}\": {path} is not the model file "
                    f"this run fitted ({fitted}): the report would describe other code; "
                    "restore the file, or run servoid identify --allow-code instead")
        module = _execute(path, text)
        cache[path] = module
    fn = getattr(module, ref.function, None)
    if fn is None or not callable(fn):
        defined = sorted(n for n, v in vars(module).items()
                         if inspect.isfunction(v) and v.__module__ == module.__name__)
        raise OptionError(f"{key} = \"{ref.file}:{ref.function}\": {path.name} has no function "
                          f"{ref.function!r}; it defines "
                          f"{', '.join(defined) if defined else 'no functions'}")
    return fn, path


def file_sha256(path: Path) -> str:
    """The SHA-256 of a file's bytes, as hex."""
    return hashlib.sha256(path.read_bytes()).hexdigest()


def executed_sha256(module: ModuleType) -> str:
    """The SHA-256 of the bytes a user's file was executed from (:func:`load_function`)."""
    return str(module.__dict__[_DIGEST])


def code_ref(fn: Callable[..., Any], name: str, what: str) -> tuple[Path, str]:
    """The file and SHA-256 a saved model names for one of its functions.

    Parameters
    ----------
    fn : callable
        The function the model calls.
    name : str
        The name it is found under in its file.
    what : str
        What it is, for messages (``"the right-hand side"``).

    Returns
    -------
    (Path, str)
        The file's absolute path and the SHA-256 of the bytes the function
        was executed from (of the file now, for a function of an ordinary
        module).

    Raises
    ------
    ModelError
        The function cannot be found again by file and name (a lambda, a
        nested function, one built in memory).
    """
    code = getattr(fn, "__code__", None)
    namespace = getattr(fn, "__globals__", None)
    path = Path(code.co_filename) if code is not None else None
    if (path is None or not isinstance(namespace, dict) or namespace.get(name) is not fn
            or not path.is_absolute() or not path.is_file()):
        raise ModelError(
            f"{what} ({getattr(fn, '__qualname__', fn)!r}) is not a function defined at the top "
            f"level of a Python file under the name {name!r}, so a saved model could not find it "
            "again: define it with def in a .py file and fit the model from there")
    digest = namespace.get(_DIGEST)
    return path, digest if isinstance(digest, str) else file_sha256(path)


def load_recorded(path: Path, digest: str, names: Sequence[str], where: str,
                  modules: dict[Path, ModuleType] | None = None) -> list[Callable[..., Any]]:
    """Execute a saved model's file, if unchanged, and return its functions.

    Parameters
    ----------
    path : Path
        The file, absolute.
    digest : str
        The SHA-256 the model recorded.
    names : sequence of str
        The functions to return.
    where : str
        The model file or results file, for messages.
    modules : dict, optional
        Files already executed in this load (path → module).

    Returns
    -------
    list of callable
        The functions, in the order of ``names``.

    Raises
    ------
    MissingFileError
        The file is gone.
    ModelError
        The file changed since the model was fitted (both hashes named),
        fails to execute, or lacks a function.
    """
    cache = {} if modules is None else modules
    module = cache.get(path)
    if module is None:
        if not path.is_file():
            raise MissingFileError(
                f"{where}: the grey-box model's code {path} is not there (moved or deleted); "
                f"put the file it was fitted with back at that path (SHA-256 {digest}), or fit "
                "the model again")
        text = path.read_bytes()
        now = hashlib.sha256(text).hexdigest()
        if now != digest:
            raise ModelError(
                f"{where}: the grey-box model was fitted with {path} of SHA-256 {digest}, and "
                f"the file has changed since (SHA-256 now {now}), so the saved parameters may "
                "not belong to its code: restore the file the model was fitted with (e.g. from "
                "version control), or fit the model again with the new file and save it anew")
        module = _execute(path, text)
        cache[path] = module
    out = []
    for name in names:
        fn = getattr(module, name, None)
        if fn is None or not callable(fn):
            raise ModelError(f"{where}: {path.name} has no function {name!r}, which the saved "
                             "model calls; the file is damaged: fit the model again")
        out.append(fn)
    return out


def _execute(path: Path, text: bytes | None = None) -> ModuleType:
    digest = hashlib.sha256(str(path).encode()).hexdigest()[:12]
    name = f"servoid_user_model_{digest}"  # private: never the name of an installed module
    spec = importlib.util.spec_from_file_location(name, path)
    if spec is None:
        raise ModelError(f"{path} cannot be loaded as a Python module")
    module = importlib.util.module_from_spec(spec)
    try:
        # compiled from its text, not through the import system's loader, which would write
        # a __pycache__ folder beside the user's file
        text = path.read_bytes() if text is None else text
        code = compile(text, str(path), "exec")
        exec(code, module.__dict__)  # noqa: S102 — the caller was allowed to run this file
    except (Exception, SystemExit) as exc:  # noqa: BLE001 — user code may raise anything
        raise user_error(exc, path.name, path) from None
    # the exact bytes its functions come from: a model saved later names them, not the file
    # as it is then
    module.__dict__[_DIGEST] = hashlib.sha256(text).hexdigest()
    return module
