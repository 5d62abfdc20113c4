"""The package layers of docs/architecture.md, held over servoid's import graph.

Every ``import`` and ``from … import`` in ``src/servoid`` is read with ``ast`` (imports inside
functions too: a lazy import is still a dependency). Two rules:

1. **Layers.** A package imports only packages of a lower layer, and within a layer only the
   packages the table below allows. So there is no import cycle between packages.
2. **Private stays private.** Another package is imported through its ``__init__``, never through
   its private modules (``servoid.estimate._arx``). servoid's own top-level private modules
   (``servoid._errors``, ``_checks``, ``_atomic`` …) are the shared core every package uses, and a
   plant's subpackage may use the private helpers of ``servoid.plants`` (its parent).
"""

from __future__ import annotations

import ast
from collections.abc import Iterator
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src"

# Bottom to top. A package may import any package of a lower layer.
LAYERS: tuple[tuple[str, ...], ...] = (
    ("core",),  # servoid._errors, _checks, _atomic, _files, _lazy, _progress, _warn, …
    ("data", "models", "integrate"),
    ("signals", "validate"),
    ("estimate",),
    ("nonlinear", "closedloop", "frequency", "bench", "datasets"),
    ("report",),  # renders what the layers below hand it; nothing below imports it
    ("workflows",),  # the method kit, the generic methods, the registry and the runner
    ("plants",),  # each actuator's subpackage; its methods are built with the kit
    ("fleet",),
    ("cli",),
    # the root's curated exports, `python -m servoid`, and the old paths kept for one release
    ("servoid", "actuators", "multistep"),
)
# Imports allowed inside one layer (importer → imported): none make a cycle.
SAME_LAYER: frozenset[tuple[str, str]] = frozenset({
    ("data", "models"),
    ("signals", "validate"),
    ("nonlinear", "closedloop"),
    ("frequency", "closedloop"),
    ("bench", "closedloop"),
})
# A plant may build on another plant's public names (the pneumatic bench writes its files the way
# the hydraulic one does); the order below keeps that acyclic.
PLANT_ORDER = ("rigid", "ehsa", "pneumatic", "ema")


def _package(module: str) -> str:
    """The package a dotted module name belongs to, as the rules name it."""
    parts = module.split(".")
    if module == "servoid" or parts[1] in ("__main__", "__version__"):
        return "servoid"
    if parts[1].startswith("_"):
        return "core"
    if parts[1] == "plants" and len(parts) > 2 and not parts[2].startswith("_"):
        return "plants." + parts[2]
    return parts[1]


def _layer(package: str) -> int:
    name = package.split(".")[0]
    for index, members in enumerate(LAYERS):
        if name in members:
            return index
    raise AssertionError(f"package {package!r} is in no layer of tests/test_architecture.py")


def _modules() -> Iterator[tuple[str, bool, Path]]:
    for path in sorted((SRC / "servoid").rglob("*.py")):
        parts = list(path.relative_to(SRC).with_suffix("").parts)
        is_package = parts[-1] == "__init__"
        if is_package:
            parts = parts[:-1]
        yield ".".join(parts), is_package, path


def _typing_only(tree: ast.Module) -> set[int]:
    """ids of the import nodes under ``if TYPE_CHECKING:`` (annotations, never executed)."""
    skip = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and ast.unparse(node.test) in ("TYPE_CHECKING",
                                                                   "typing.TYPE_CHECKING"):
            skip.update(id(inner) for stmt in node.body for inner in ast.walk(stmt))
    return skip


def _imports(module: str, is_package: bool, path: Path) -> Iterator[tuple[str, int]]:
    """(imported module, line) for every servoid import; ``from m import n`` gives m and m.n."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    skip = _typing_only(tree)
    for node in ast.walk(tree):
        if id(node) in skip:
            continue
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = module.split(".") if is_package else module.split(".")[:-1]
                base = base[: len(base) - node.level + 1]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            if target == "servoid":  # `from servoid import _errors` imports that module
                for alias in node.names:
                    yield f"servoid.{alias.name}", node.lineno
            elif target.startswith("servoid."):
                yield target, node.lineno
                for alias in node.names:
                    # a name may be a submodule (`from . import _x`); a private one counts
                    if alias.name.startswith("_") and not alias.name.startswith("__"):
                        yield f"{target}.{alias.name}", node.lineno
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name == "servoid" or alias.name.startswith("servoid."):
                    yield alias.name, node.lineno


def _private_part(target: str, package: str) -> bool:
    """Whether `target` reaches below `package`'s __init__ into a private module."""
    prefix = "servoid." + package if package != "servoid" else "servoid"
    rest = target[len(prefix):].split(".")[1:]
    return any(part.startswith("_") and not part.startswith("__") for part in rest)


def _edges() -> list[tuple[str, int, str, str, str]]:
    """(file, line, importer package, imported package, imported module) across packages."""
    found = []
    for module, is_package, path in _modules():
        source = _package(module)
        for target, line in _imports(module, is_package, path):
            imported = _package(target)
            if imported != source:
                found.append((str(path.relative_to(SRC)), line, source, imported, target))
    return found


def _layer_problem(source: str, imported: str) -> str | None:
    if source == "servoid" or imported == "core":
        return None
    if source.startswith("plants.") and imported.startswith("plants."):
        a, b = source.split(".")[1], imported.split(".")[1]
        if a in PLANT_ORDER and b in PLANT_ORDER and PLANT_ORDER.index(b) < PLANT_ORDER.index(a):
            return None
        return f"plant {a} may not import plant {b} (order: {', '.join(PLANT_ORDER)})"
    if source.startswith("plants.") and imported == "plants":
        return None  # a plant uses its parent's Plant record and helpers
    if source == "plants" and imported.startswith("plants."):
        return None  # servoid.plants lists its subpackages' Plant records
    below, above = _layer(imported), _layer(source)
    if below < above or (below == above and (source, imported) in SAME_LAYER):
        return None
    return f"{source} (layer {above}) may not import {imported} (layer {below})"


def _private_problem(source: str, imported: str, target: str) -> str | None:
    if imported == "core":
        return None
    if source.startswith("plants.") and imported == "plants":
        return None  # a plant may use the private helpers of servoid.plants
    if _private_part(target, imported):
        return f"{target} is private to {imported}: import it from servoid.{imported}"
    return None


def test_every_package_is_in_a_layer():
    packages = {_package(module) for module, _, _ in _modules()}
    for package in packages:
        _layer(package)
    plants = {p.split(".")[1] for p in packages if p.startswith("plants.")}
    assert plants == set(PLANT_ORDER), "add the new plant to PLANT_ORDER"


def test_layers_hold():
    broken = sorted({f"{file}:{line}: {problem}"
                     for file, line, source, imported, _ in _edges()
                     if (problem := _layer_problem(source, imported))})
    assert not broken, "imports against docs/architecture.md:\n" + "\n".join(broken)


def test_no_import_of_another_packages_private_modules():
    broken = sorted({f"{file}:{line}: {problem}"
                     for file, line, source, imported, target in _edges()
                     if (problem := _private_problem(source, imported, target))})
    assert not broken, f"{len(broken)} private imports:\n" + "\n".join(broken)


@pytest.mark.parametrize(("source", "imported", "allowed"), [
    ("estimate", "models", True),
    ("models", "estimate", False),      # the cycle models/_file → estimate is what this catches
    ("workflows", "plants", False),     # workflows names plant methods by module string only
    ("plants.pneumatic", "plants.ehsa", True),
    ("plants.ehsa", "plants.pneumatic", False),
    ("plants.ema", "cli", False),
])
def test_the_rules_can_fail(source, imported, allowed):
    assert (_layer_problem(source, imported) is None) is allowed


def test_private_rule_can_fail():
    assert _private_problem("workflows", "estimate", "servoid.estimate._arx") is not None
    assert _private_problem("workflows", "estimate", "servoid.estimate") is None
    assert _private_problem("plants.ema", "plants", "servoid.plants._common") is None
    assert _private_problem("plants.ema", "plants.ehsa", "servoid.plants.ehsa._bench") is not None
