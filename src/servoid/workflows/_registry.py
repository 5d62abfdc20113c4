"""The method registry: what ``[identify] method = …`` can name.

A method is one module that declares

- its ``[identify]`` options (:class:`Option`: name, default, check, help),
- the other tables of the experiment file it reads (``[loop]``, ``[validation]``),
- its run: ``run(spec, options, truth) -> result``, computing without writing.

The result (an :class:`Identification`) contributes the rest: its console
text (``__str__``), ``results.json`` (``to_dict``), its figures
(``figures``: file name → writer), its report page (``page``) and the
verdict the page opens with (``verdict``: a :class:`~servoid.report.Verdict`
built from the result's own numbers; a result without one is judged from
its ``results.json``).  The
command line, the TOML loader, the report writer and the fleet runner see
only this registry; :func:`servoid.workflows.identify` walks
spec → method → result → files.  Adding a method is one module and one
line in ``_methods.py``.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import TYPE_CHECKING, Any, Protocol

from .._checks import as_mapping, as_str, as_str_list, type_error
from .._errors import OptionError

if TYPE_CHECKING:
    from ..data import ExperimentSpec
    from ..report import Page

__all__ = ["Identification", "Method", "Option", "Runner"]

Check = Callable[[Any, str, str], Any]
FigureWriter = Callable[[Path, bool], None]


@dataclass(frozen=True)
class Option:
    """One ``[identify]`` key of a method.

    Attributes
    ----------
    name : str
        The key.
    default : object
        Value when the key is absent (already in its checked form).
    check : callable
        ``check(value, where, name) -> value``: the value in canonical form,
        or a servoid error naming the key, the value and what is expected.
    help : str
        One line for ``servoid methods`` and the docs: what it sets, its
        unit and its values.
    """

    name: str
    default: Any
    check: Check
    help: str

    def __post_init__(self) -> None:
        as_str("name", self.name)
        if not callable(self.check):
            raise type_error("check", self.check, "a callable check(value, where, name)")
        as_str("help", self.help, empty=True)


class Identification(Protocol):
    """What a method's run returns: one result, printable, writable."""

    folder: Path | None
    files: tuple[Path, ...]

    def to_dict(self) -> dict[str, Any]:
        """Everything in ``results.json``."""

    def inputs(self) -> tuple[Path, ...]:
        """Every file the run read (never to be written over)."""

    def figures(self) -> Mapping[str, FigureWriter]:
        """Figure file name → ``writer(path, overwrite)``."""

    def page(self, files: Mapping[str, Path]) -> Page:
        """The report page, given the written figure files."""


class Runner(Protocol):
    """``run(spec, options, truth)`` of a method."""

    def __call__(self, spec: ExperimentSpec, options: Mapping[str, Any],
                 truth: Mapping[str, float] | None) -> Identification: ...


@dataclass(frozen=True)
class Method:
    """An identification method the experiment file can name.

    Attributes
    ----------
    name : str
        The value of ``[identify] method``.
    summary : str
        One line: what it identifies, from which data.
    options : tuple of Option
        Its ``[identify]`` keys (``method`` itself is implied).
    run : callable
        ``run(spec, options, truth) -> Identification``, writing nothing.
    tables : tuple of str
        Other tables of the experiment file it reads (``"loop"``,
        ``"validation"``); any other one present is refused, not ignored.
    """

    name: str
    summary: str
    options: tuple[Option, ...]
    run: Runner
    tables: tuple[str, ...] = ("validation",)
    _index: Mapping[str, Option] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        as_str("name", self.name)
        as_str("summary", self.summary, empty=True)
        if isinstance(self.options, (str, bytes)) or not isinstance(self.options, Sequence) \
                or not all(isinstance(o, Option) for o in self.options):
            raise type_error("options", self.options, "a tuple of Option")
        if not callable(self.run):
            raise type_error("run", self.run, "a callable run(spec, options, truth)")
        object.__setattr__(self, "options", tuple(self.options))
        object.__setattr__(self, "tables", tuple(as_str_list("tables", self.tables)))
        index = {o.name: o for o in self.options}
        if len(index) != len(self.options) or "method" in index:
            raise OptionError(f"method {self.name!r}: option names must be unique, not 'method'")
        object.__setattr__(self, "_index", MappingProxyType(index))

    @property
    def keys(self) -> tuple[str, ...]:
        """Every valid ``[identify]`` key, ``method`` first."""
        return ("method", *self._index)

    def parse(self, table: Mapping[str, Any]) -> dict[str, Any]:
        """Check an ``[identify]`` table; return every option, defaults filled.

        Raises
        ------
        OptionError
            An unknown key (the message lists the valid ones).
        """
        table = as_mapping("table", table, where="[identify]")
        unknown = sorted(set(table) - set(self.keys))
        if unknown:
            raise OptionError(
                f"unknown key(s) in [identify]: {', '.join(unknown)}; valid keys for "
                f"method = \"{self.name}\" are {', '.join(self.keys)}"
            )
        where = "[identify]"
        out = {}
        for option in self.options:
            if option.name in table:
                out[option.name] = option.check(table[option.name], where, option.name)
            else:
                out[option.name] = option.default
        return out

    def describe(self) -> str:
        """The method and its options as text (``servoid methods NAME``)."""
        width = max((len(o.name) for o in self.options), default=0)
        lines = [f"{self.name}: {self.summary}", "", "[identify] keys:",
                 f"  {'method':<{width}}  = \"{self.name}\""]
        for o in self.options:
            lines.append(f"  {o.name:<{width}}  {o.help} (default {toml_value(o.default)})")
        if self.tables:
            lines += ["", "reads also: " + ", ".join(f"[{t}]" for t in self.tables)]
        return "\n".join(lines)

    def to_dict(self) -> dict[str, Any]:
        """Name, summary, tables and options as plain data."""
        return {"name": self.name, "summary": self.summary, "tables": list(self.tables),
                "options": [{"name": o.name, "default": o.default, "help": o.help}
                            for o in self.options]}


def registry(methods: Sequence[Method]) -> Mapping[str, Method]:
    """Return a read-only name → method mapping; names must be unique."""
    out: dict[str, Method] = {}
    for m in methods:
        if m.name in out:
            raise ValueError(f"method {m.name!r} is registered twice")
        out[m.name] = m
    return MappingProxyType(out)


def toml_value(value: Any) -> str:
    """A value as the experiment file writes it (``true``, ``"text"``, ``[1, 2]``; ``none``)."""
    if value is None:
        return "none"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return f'"{value}"'
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    return str(value)
