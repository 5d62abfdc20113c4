"""The method registry: what ``[identify] method = …`` can name, and what every run returns.

A method is one module that declares

- its ``[identify]`` options (:class:`Option`: name, default, check, help),
- every other table of the experiment file it reads: ``"validation"`` (the
  spec's own table, which it uses) and a :class:`TableSchema` for a table
  whose keys are the method's (``[loop]``), checked like ``[identify]``,
- its run: ``run(spec, options, truth) -> result``, computing without
  writing; ``options`` holds the checked ``[identify]`` values and, under
  ``"[loop]"`` (the table's name in brackets), the checked values of each
  table it declares a schema for,
- what the registry's callers need to know about it, as properties rather
  than by its name (:attr:`Method.multi_output`, :attr:`Method.runs_code`,
  :attr:`Method.warm_up`) and an example record (:attr:`Method.example`)
  that the conformance suite runs it on.

The result implements one contract, :class:`Identification`: its console
text (``__str__``), ``summary()`` (the scalar parameters with value, σ,
interval and unit, the fit and the verdict's decision: what a fleet row
keeps), ``models()`` (name → model), ``verdict()`` (the
:class:`~servoid.report.Verdict` the report opens with, from the result's
own numbers), ``sections(files)`` and ``page(files)`` (the report),
``figures()`` (file name → writer), ``inputs()`` and ``to_dict()``
(``results.json``).  The command line, the TOML loader, the report writer
and the fleet runner see only this registry and this contract:
:func:`servoid.workflows.identify` walks spec → method → result → files.
Adding a method is one module and one line in ``_methods.py``.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

from .._checks import as_mapping, as_str, type_error
from .._errors import OptionError

if TYPE_CHECKING:
    from ..data import ExperimentSpec
    from ..report import Page, Section, Verdict
    from ._summary import RecordSummary

__all__ = ["CONTRACT", "Identification", "Method", "Option", "Runner", "TableSchema"]

Check = Callable[[Any, str, str], Any]
FigureWriter = Callable[[Path, bool], None]
#: ``when(options, table) -> bool``: whether a run with these ``[identify]`` options reads the table
When = Callable[[Mapping[str, Any], Mapping[str, Any]], bool]
#: ``example(folder, seed) -> experiment file``: a small record the method runs on in seconds
Example = Callable[[Path, int], Path]

#: The methods of the result contract every registered method's result implements.
CONTRACT = ("summary", "models", "verdict", "sections", "page", "figures", "inputs", "to_dict")


@dataclass(frozen=True)
class Option:
    """One key of a method's table (``[identify]``, ``[loop]``).

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


@dataclass(frozen=True)
class TableSchema:
    """A table of the experiment file whose keys a method declares (``[loop]``).

    Attributes
    ----------
    name : str
        The table (``"loop"``).
    options : tuple of Option
        Its keys; a key absent from the file takes its option's default.
    help : str
        What the table describes, in one line.
    when : callable, optional
        ``when(options, table) -> bool``: whether a run with these checked
        ``[identify]`` options reads the table; default always.  A table a
        run does not read is left as it is (``[loop]`` describes the rig
        whatever the method), never checked.
    when_text : str
        ``when`` in words, for ``servoid methods`` (``'instrument = "r"'``).
    """

    name: str
    options: tuple[Option, ...]
    help: str = ""
    when: When | None = None
    when_text: str = ""

    def __post_init__(self) -> None:
        as_str("name", self.name)
        if isinstance(self.options, (str, bytes)) or not isinstance(self.options, Sequence) \
                or not all(isinstance(o, Option) for o in self.options):
            raise type_error("options", self.options, "a tuple of Option")
        object.__setattr__(self, "options", tuple(self.options))
        if len({o.name for o in self.options}) != len(self.options):
            raise OptionError(f"table [{self.name}]: key names must be unique")
        if self.when is not None and not callable(self.when):
            raise type_error("when", self.when, "a callable when(options, table) -> bool")

    @property
    def keys(self) -> tuple[str, ...]:
        """Every valid key, in declaration order."""
        return tuple(o.name for o in self.options)

    def parse(self, table: Mapping[str, Any], method: str = "") -> dict[str, Any]:
        """Check the table; return every key, defaults filled.

        Raises
        ------
        OptionError
            An unknown key (the message lists the valid ones and names the
            method that reads them).
        """
        where = f"[{self.name}]"
        table = as_mapping("table", table, where=where)
        unknown = sorted(set(table) - set(self.keys))
        if unknown:
            reader = f" (method = \"{method}\" reads these)" if method else ""
            raise OptionError(f"unknown key(s) in {where}: {', '.join(map(str, unknown))}; valid "
                              f"keys are {', '.join(self.keys)}{reader}")
        return {o.name: o.check(table[o.name], where, o.name) if o.name in table else o.default
                for o in self.options}

    def reads(self, options: Mapping[str, Any], table: Mapping[str, Any]) -> bool:
        """Whether a run with these ``[identify]`` options reads the table."""
        return self.when is None or bool(self.when(options, table))

    def lines(self) -> list[str]:
        """The table's keys as ``servoid methods NAME`` lists them."""
        width = max((len(o.name) for o in self.options), default=0)
        head = f"[{self.name}] keys" + (f" ({self.help})" if self.help else "")
        if self.when_text:
            head += f", read when {self.when_text}"
        return [head + ":", *(f"  {o.name:<{width}}  {o.help} (default {toml_value(o.default)})"
                              for o in self.options)]

    def to_dict(self) -> dict[str, Any]:
        """Name, help, condition and keys as plain data."""
        return {"name": self.name, "help": self.help, "read_when": self.when_text or "always",
                "options": [{"name": o.name, "default": o.default, "help": o.help}
                            for o in self.options]}


@runtime_checkable
class Identification(Protocol):
    """What a method's run returns: one result, summarised, judged, printable, writable.

    ``write_results``, the report's verdict box and provenance, the fleet
    row and ``load_results`` use these and nothing else: no caller reads a
    method's ``results.json`` back, nor asks which method made a result.
    """

    folder: Path | None
    files: tuple[Path, ...]

    def summary(self) -> RecordSummary:
        """Scalar parameters (value, σ, 95 % interval, unit), fit, residual tests, decision."""

    def models(self) -> Mapping[str, Any]:
        """Name → identified model (a servoid model object), possibly empty."""

    def verdict(self) -> Verdict:
        """What the report decides, from the result's own numbers."""

    def sections(self, files: Mapping[str, Path]) -> tuple[Section, ...]:
        """The report's sections after the verdict box, given the written figure files."""

    def page(self, files: Mapping[str, Path]) -> Page:
        """The report page (title, subtitle, :meth:`sections`, metadata)."""

    def figures(self) -> Mapping[str, FigureWriter]:
        """Figure file name → ``writer(path, overwrite)``."""

    def inputs(self) -> tuple[Path, ...]:
        """Every file the run read (never to be written over)."""

    def to_dict(self) -> dict[str, Any]:
        """Everything in ``results.json`` (``"summary"`` and ``"verdict"`` included)."""


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
    tables : tuple of str or TableSchema
        Other tables of the experiment file it reads: ``"validation"``
        (read by the spec; one present that the method does not list is
        refused, not ignored) and a :class:`TableSchema` for each table of
        its own keys (``[loop]``).  Given as names and schemas; kept as the
        tables' names, the schemas in :attr:`schemas`.
    multi_output : bool
        Fits every output channel when ``[identify] output`` is not set (a
        record with several y channels is not refused).
    runs_code : bool
        Its results hold a model that runs the user's Python code: rebuilt,
        and re-rendered, only with ``allow_code``.
    warm_up : callable, optional
        ``warm_up()`` loads its compiled kernels (a fleet's workers call it
        before their first record).
    example : callable, optional
        ``example(folder, seed) -> experiment file``: writes a small record
        the method identifies in seconds (the conformance suite runs every
        registered method on its own; a registered method must have one).
    """

    name: str
    summary: str
    options: tuple[Option, ...]
    run: Runner
    tables: tuple[str | TableSchema, ...] = ("validation",)
    multi_output: bool = False
    runs_code: bool = False
    warm_up: Callable[[], None] | None = field(default=None, compare=False)
    example: Example | None = field(default=None, compare=False)
    _index: Mapping[str, Option] = field(init=False, repr=False, compare=False)
    _schemas: Mapping[str, TableSchema] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        as_str("name", self.name)
        as_str("summary", self.summary, empty=True)
        if isinstance(self.options, (str, bytes)) or not isinstance(self.options, Sequence) \
                or not all(isinstance(o, Option) for o in self.options):
            raise type_error("options", self.options, "a tuple of Option")
        if not callable(self.run):
            raise type_error("run", self.run, "a callable run(spec, options, truth)")
        object.__setattr__(self, "options", tuple(self.options))
        tables = self.tables
        if isinstance(tables, (str, bytes, TableSchema)) or not isinstance(tables, Sequence) \
                or not all(isinstance(t, (str, TableSchema)) for t in tables):
            raise type_error("tables", tables, "a tuple of table names and TableSchema")
        schemas = {t.name: t for t in tables if isinstance(t, TableSchema)}
        names = tuple(t.name if isinstance(t, TableSchema) else as_str("tables", t)
                      for t in tables)
        if len(set(names)) != len(names):
            raise OptionError(f"method {self.name!r}: a table is listed twice")
        object.__setattr__(self, "tables", names)
        object.__setattr__(self, "_schemas", MappingProxyType(schemas))
        for name in ("multi_output", "runs_code"):
            if not isinstance(getattr(self, name), bool):
                raise type_error(name, getattr(self, name), "True or False")
        for name in ("warm_up", "example"):
            if getattr(self, name) is not None and not callable(getattr(self, name)):
                raise type_error(name, getattr(self, name), "a callable or None")
        index = {o.name: o for o in self.options}
        if len(index) != len(self.options) or "method" in index or \
                any(f"[{t}]" in index for t in names):
            raise OptionError(f"method {self.name!r}: option names must be unique, not 'method'")
        object.__setattr__(self, "_index", MappingProxyType(index))

    @property
    def keys(self) -> tuple[str, ...]:
        """Every valid ``[identify]`` key, ``method`` first."""
        return ("method", *self._index)

    @property
    def schemas(self) -> Mapping[str, TableSchema]:
        """Table name → the schema of each table of its own keys it reads (``"loop"``)."""
        return self._schemas

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
                f"unknown key(s) in [identify]: {', '.join(map(str, unknown))}; valid keys for "
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

    def parse_tables(self, tables: Mapping[str, Mapping[str, Any]],
                     options: Mapping[str, Any]) -> dict[str, dict[str, Any]]:
        """Check each table of its own keys that a run with ``options`` reads.

        Parameters
        ----------
        tables : mapping
            Table name → the table as the experiment file holds it (an
            absent table is an empty one).
        options : mapping
            The checked ``[identify]`` options (a schema's ``when`` reads them).

        Returns
        -------
        dict
            ``"[name]"`` → the checked table, defaults filled, for each table
            read; what the run finds in its options under that key.
        """
        out = {}
        for name, schema in self._schemas.items():
            table = tables.get(name) or {}
            if schema.reads(options, table):
                out[f"[{name}]"] = schema.parse(table, self.name)
        return out

    def describe(self) -> str:
        """The method and its options as text (``servoid methods NAME``)."""
        width = max((len(o.name) for o in self.options), default=0)
        lines = [f"{self.name}: {self.summary}", "", "[identify] keys:",
                 f"  {'method':<{width}}  = \"{self.name}\""]
        for o in self.options:
            lines.append(f"  {o.name:<{width}}  {o.help} (default {toml_value(o.default)})")
        for schema in self._schemas.values():
            lines += ["", *schema.lines()]
        if self.tables:
            lines += ["", "reads also: " + ", ".join(f"[{t}]" for t in self.tables)]
        return "\n".join(lines)

    def to_dict(self) -> dict[str, Any]:
        """Name, summary, tables (with the keys of its own) and options as plain data."""
        return {"name": self.name, "summary": self.summary, "tables": list(self.tables),
                "options": [{"name": o.name, "default": o.default, "help": o.help}
                            for o in self.options],
                "table_keys": {name: schema.to_dict() for name, schema in self._schemas.items()},
                "multi_output": self.multi_output, "runs_code": self.runs_code}


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
