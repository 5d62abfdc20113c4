"""Grammar-aware inputs for the fuzzers of servoid's document loaders.

Shared by the suite's reduced run (``test_loader_fuzz.py``: fixed seeds, a
few seconds) and the long run of ``benchmarks/bench_fuzz.py``.  Loaders:

- ``"model"``: :func:`servoid.load_model` on a model file (JSON);
- ``"results"``: :func:`servoid.load_results`, ``greybox_record`` and
  :func:`servoid.workflows.rerender` (which reads the run's
  ``manifest.json``) on a results folder;
- ``"spec"``: :func:`servoid.data.load_experiment_spec` on an experiment
  file (TOML), then its records and a write/read round trip;
- ``"fleet"``: ``servoid.fleet.load_fleet_spec`` on a fleet file (TOML).

An input starts from a valid document of the format (``loader_seeds/``,
made by ``loader_seeds/make_seeds.py``; the experiment and fleet files are
written here), parsed into a tree.  One to four mutations follow the
format's grammar: a value of the wrong type, a key deleted or added (from
every key the format's seeds use, or an odd one), an array reshaped
(truncated, extended, ragged, wrapped, flattened, emptied), two subtrees
swapped, a kind word replaced by another (``"type": "BlockModel"`` on a
transfer function), a subtree grafted from another seed, a number replaced
by an edge value (±0, 5e-324, 1e308, ±inf, NaN, 2⁶³, 10⁴⁰⁰, a 5000-digit
integer), a string replaced or damaged (empty, NUL, right-to-left mark,
lone surrogate, 200 000 characters, base64, a path outside the folder), or
a value nested thousands of levels deep.  The tree is written back by the
writers here, which write what servoid's never would (NaN, 10⁴⁰⁰, TOML
dates, deep nesting); then one input in five also gets byte mutations
(a bit flip, an inserted or deleted run, a truncation).

Every choice is drawn from ``random.Random(f"{seed}:{loader}:{index}")``, so
an input is rebuilt from its index; :func:`make_input` returns the files to
write, the call mode and a description of the mutations.
"""

from __future__ import annotations

import copy
import json
import math
import random
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path
from typing import Any

from servoid import ServoidError

__all__ = ["LOADERS", "N_MODES", "SEED", "Input", "make_input", "prepare", "run_input",
           "seed_input", "seed_names"]

SEED = 20261128
LOADERS = ("model", "results", "spec", "fleet")
SEEDS = Path(__file__).resolve().parent / "loader_seeds"
N_MODES = {"model": 2, "results": 4, "spec": 3, "fleet": 1}
_DEPTHS = (40, 400, 1200, 5000, 100_000)


@dataclass(frozen=True)
class Input:
    """One generated input: files (name → bytes), the call mode, what was done."""

    loader: str
    index: int
    files: dict[str, bytes]
    mode: int
    ops: tuple[str, ...] = field(default=())


# -- values the writers can express ------------------------------------------------------------


@dataclass(frozen=True)
class Raw:
    """Text written as is: JSON and TOML spellings (None: not expressible, write null/skip)."""

    json: str | None
    toml: str | None
    label: str


@dataclass(frozen=True)
class Deep:
    """A value nested ``depth`` levels deep: arrays or tables."""

    depth: int
    tables: bool


_RAW = (
    Raw("1" + "0" * 400, "1" + "0" * 400, "10**400"),
    Raw("-1" + "0" * 400, "-1" + "0" * 400, "-10**400"),
    Raw("9" * 5000, "9" * 5000, "5000-digit integer"),
    Raw("1e400", "1e400", "1e400 (inf)"),
    Raw("-1e400", "-1e400", "-1e400"),
    Raw("1e-400", "1e-400", "1e-400 (0)"),
    Raw("NaN", "nan", "NaN"),
    Raw("Infinity", "inf", "inf"),
    Raw("-Infinity", "-inf", "-inf"),
    Raw("-0", "-0", "-0"),
    Raw(None, "1979-05-27", "a TOML date"),
    Raw(None, "07:32:00", "a TOML time"),
    Raw(None, "1979-05-27T07:32:00-08:00", "a TOML datetime"),
    Raw(None, "0xDEADBEEF", "a hex integer"),
    Raw(None, "1_000", "digit grouping"),
    Raw(None, "'''multi\nline'''", "a multi-line literal string"),
    Raw('"\\ud800"', None, "a lone surrogate"),
    Raw('"\\u0000"', '"\\u0000"', "a NUL character"),
)
_NUMBERS: tuple[Any, ...] = (
    0, -1, 1, 2, 3, 0.5, -0.0, 1e-300, 5e-324, 1e308, -1e308, 1.7976931348623157e308,
    math.inf, -math.inf, math.nan, 2**31, 2**53 + 1, 2**63, 2**64, -(2**63) - 1, 10**400,
    -(10**400), 10**20, 1e16, 4.9e-324, 100000, True, False,
)
_STRINGS = (
    "", " ", "\x00", "a\x00b", "é", "\u202e", "\U0001f600", "\ud800", "x" * 200_000,
    "AAAAAAAA8D8=", "not base64!!", "1.0", "NaN", "inf", "0x10", "null", "true",
    "../../outside.csv", "/nonexistent/servoid-fuzz.csv", ".", "..", "data.csv\n",
    "C:\\temp\\x.csv", "~/x.csv", "'", '"', "\\", "[data]", "a" * 64, "\t", "\r\n",
    "=HYPERLINK(\"x\")", "<script>", "%s%n", "{}", "[]", "$x^2$",
)


def _hostile(rng: random.Random) -> Any:
    """A value of any kind: the wrong type, an edge number, an odd string, a shape."""
    pick = rng.randrange(12)
    if pick == 0:
        return None
    if pick in (1, 2):
        return rng.choice(_NUMBERS)
    if pick == 3:
        return rng.choice(_STRINGS)
    if pick == 4:
        return rng.choice(_RAW)
    if pick == 5:
        return Deep(rng.choice(_DEPTHS), rng.random() < 0.3)
    if pick == 6:
        return []
    if pick == 7:
        return {}
    if pick == 8:
        return [rng.choice(_NUMBERS) for _ in range(rng.choice((1, 2, 3, 7, 1000)))]
    if pick == 9:
        return [[1.0, 2.0], [3.0]] if rng.random() < 0.5 else [[1.0], "a", None]
    if pick == 10:
        return {"a": 1, "": None, "\x00": [1]}
    return rng.choice((True, False, 0, "x"))


# -- the tree ----------------------------------------------------------------------------------

Path_ = tuple[Any, ...]


def _paths(node: Any, prefix: Path_ = ()) -> Iterator[tuple[Path_, Any]]:
    yield prefix, node
    if isinstance(node, dict):
        for k, v in node.items():
            yield from _paths(v, (*prefix, k))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            yield from _paths(v, (*prefix, i))


def _get(tree: Any, path: Path_) -> Any:
    for key in path:
        tree = tree[key]
    return tree


def _set(tree: Any, path: Path_, value: Any) -> Any:
    if not path:
        return value
    _get(tree, path[:-1])[path[-1]] = value
    return tree


def _label(path: Path_) -> str:
    return "".join(f"[{p}]" if isinstance(p, int) else f".{p}" for p in path) or "(root)"


def _short(value: Any) -> str:
    if isinstance(value, Raw):
        return value.label
    if isinstance(value, Deep):
        return f"{'tables' if value.tables else 'arrays'} nested {value.depth} deep"
    text = repr(value)
    return text if len(text) < 60 else text[:40] + f"…({len(text)} chars)"


@dataclass(frozen=True)
class _Grammar:
    """What a format's seeds hold: every key, every word, every subtree."""

    keys: tuple[str, ...]
    words: tuple[str, ...]
    subtrees: tuple[Any, ...]


def _grammar(trees: list[Any]) -> _Grammar:
    keys: dict[str, None] = {}
    words: dict[str, None] = {}
    subtrees: list[Any] = []
    for tree in trees:
        for path, node in _paths(tree):
            if path and isinstance(path[-1], str):
                keys[path[-1]] = None
            if isinstance(node, str) and len(node) < 40 and "@" not in node:
                words[node] = None
            if isinstance(node, (dict, list)) and path and len(json.dumps(node)) < 4000:
                subtrees.append(node)
    return _Grammar(tuple(keys), tuple(words), tuple(subtrees))


def _mutate(tree: Any, grammar: _Grammar, rng: random.Random) -> tuple[Any, str]:
    """One grammar mutation of ``tree`` (in place where it can); its description."""
    nodes = list(_paths(tree))
    op = rng.randrange(10)
    path, node = nodes[rng.randrange(1, len(nodes))] if len(nodes) > 1 else nodes[0]
    where = _label(path)
    if op == 0:  # a value of another type
        value = _hostile(rng)
        return _set(tree, path, value), f"set {where} = {_short(value)}"
    if op == 1 and path:  # delete a key or an element
        parent = _get(tree, path[:-1])
        del parent[path[-1]]
        return tree, f"delete {where}"
    if op == 2:  # add a key (a known one in the wrong place, or an odd one)
        tables = [(p, n) for p, n in nodes if isinstance(n, dict)]
        if tables:
            at, table = rng.choice(tables)
            key = rng.choice(grammar.keys) if rng.random() < 0.7 else rng.choice(
                ("", "\x00", "é", "x" * 300, "Type", "__class__", "1"))
            value = _hostile(rng) if rng.random() < 0.6 else copy.deepcopy(
                rng.choice(grammar.subtrees) if grammar.subtrees else 1)
            table[key] = value
            return tree, f"add {_label((*at, key))} = {_short(value)}"
    if op == 3:  # reshape an array
        arrays = [(p, n) for p, n in nodes if isinstance(n, list)]
        if arrays:
            at, array = rng.choice(arrays)
            new, how = _reshape(array, rng)
            return _set(tree, at, new), f"reshape {_label(at)}: {how}"
    if op == 4 and len(nodes) > 2:  # swap two subtrees
        (pa, a), (pb, b) = rng.sample(nodes[1:], 2)
        if not _overlap(pa, pb):
            a, b = copy.deepcopy(a), copy.deepcopy(b)
            _set(tree, pa, b)
            _set(tree, pb, a)
            return tree, f"swap {_label(pa)} and {_label(pb)}"
    if op == 5:  # a kind word where another belongs (a wrong type, method, shape)
        strings = [(p, n) for p, n in nodes if isinstance(n, str) and p]
        if strings and grammar.words:
            at, _ = rng.choice(strings)
            word = rng.choice(grammar.words)
            return _set(tree, at, word), f"set {_label(at)} = {word!r}"
    if op == 6:  # an edge number where a number is
        numbers = [(p, n) for p, n in nodes if isinstance(n, (int, float)) and p]
        if numbers:
            at, _ = rng.choice(numbers)
            value = rng.choice(_NUMBERS + _RAW[:10])
            return _set(tree, at, value), f"set {_label(at)} = {_short(value)}"
    if op == 7:  # a damaged string
        strings = [(p, n) for p, n in nodes if isinstance(n, str) and p]
        if strings:
            at, text = rng.choice(strings)
            new = _damage(text, rng)
            return _set(tree, at, new), f"set {_label(at)} = {_short(new)}"
    if op == 8 and grammar.subtrees:  # a subtree from another seed
        value = copy.deepcopy(rng.choice(grammar.subtrees))
        return _set(tree, path, value), f"graft at {where}: {_short(value)}"
    if op == 9:
        value = Deep(rng.choice(_DEPTHS), rng.random() < 0.3)
        return _set(tree, path, value), f"set {where} = {_short(value)}"
    value = _hostile(rng)  # the op did not apply here: a wrong type instead
    return _set(tree, path, value), f"set {where} = {_short(value)}"


def _overlap(a: Path_, b: Path_) -> bool:
    n = min(len(a), len(b))
    return a[:n] == b[:n]


def _reshape(array: list[Any], rng: random.Random) -> tuple[Any, str]:
    how = rng.randrange(9)
    if how == 0:
        return array[:-1], "last element dropped"
    if how == 1:
        return array + [copy.deepcopy(array[-1]) if array else 1.0], "last element repeated"
    if how == 2:
        return [], "emptied"
    if how == 3:
        return [array], "wrapped in an array"
    if how == 4:
        flat = [x for v in array for x in (v if isinstance(v, list) else [v])]
        return flat, "flattened one level"
    if how == 5 and array:
        k = rng.randrange(len(array))
        return array[:k] + [[array[k]]] + array[k + 1:], f"element {k} wrapped (ragged)"
    if how == 6:
        return array * 50, "repeated 50 times"
    if how == 7 and array:
        return array[0], "replaced by its first element"
    return array + [_hostile(rng)], "a value of another type appended"


def _damage(text: str, rng: random.Random) -> str:
    how = rng.randrange(6)
    if how == 0:
        return rng.choice(_STRINGS)
    if how == 1:
        k = rng.randrange(len(text) + 1)
        return text[:k] + rng.choice(("\x00", "\ud800", "\u202e", "/", "..", "\n", "é")) + text[k:]
    if how == 2:
        return text[: rng.randrange(len(text) + 1)]
    if how == 3:
        return text * 1000
    if how == 4:
        return text.upper()
    return " " + text + " "


# -- writers -----------------------------------------------------------------------------------


def write_json(tree: Any) -> str:
    """JSON text of a tree with Raw and Deep values (NaN and huge integers as they come)."""
    specials: list[Any] = []

    def mark(node: Any) -> Any:  # Raw and Deep become marker strings, replaced after dumps
        if isinstance(node, (Raw, Deep)):
            specials.append(node)
            return f"\x01{len(specials) - 1}\x01"
        if isinstance(node, dict):
            return {str(k): mark(v) for k, v in node.items()}
        if isinstance(node, list):
            return [mark(v) for v in node]
        return node

    text = json.dumps(mark(tree))  # ensure_ascii: a lone surrogate is written as \ud800
    for k, node in enumerate(specials):
        text = text.replace(f'"\\u0001{k}\\u0001"', _json_special(node), 1)
    return text


def _json_special(value: Any) -> str:
    if isinstance(value, Raw):
        return value.json if value.json is not None else "null"
    if value.tables:
        return '{"a":' * value.depth + "1" + "}" * value.depth
    return "[" * value.depth + "]" * value.depth


def write_toml(doc: Any) -> str:
    """TOML text of a tree: tables as [headers], tables in arrays inline; None leaves a key out."""
    if not isinstance(doc, dict):
        return f"value = {_toml_value(doc)}\n"
    lines: list[str] = []
    _toml_table(doc, [], lines)
    return "\n".join(lines) + "\n"


def _toml_table(table: dict[str, Any], header: list[str], lines: list[str]) -> None:
    if header:
        lines.append("[" + ".".join(_toml_key(h) for h in header) + "]")
    nested = []
    for k, v in table.items():
        if isinstance(v, dict) and v and len(header) < 4:
            nested.append((k, v))
        elif v is not None:
            lines.append(f"{_toml_key(k)} = {_toml_value(v)}")
    for k, v in nested:
        _toml_table(v, [*header, k], lines)


def _toml_key(key: Any) -> str:
    text = str(key)
    if text and all(c.isascii() and (c.isalnum() or c in "_-") for c in text):
        return text
    return _toml_string(text)


def _toml_value(value: Any) -> str:
    if isinstance(value, Raw):
        return value.toml if value.toml is not None else '""'
    if isinstance(value, Deep):
        if value.tables:
            return "{a = " * value.depth + "1" + "}" * value.depth
        return "[" * value.depth + "]" * value.depth
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        return repr(value)
    if isinstance(value, str):
        return _toml_string(value)
    if isinstance(value, list):
        return "[" + ", ".join(_toml_value(v) for v in value if v is not None) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{_toml_key(k)} = {_toml_value(v)}" for k, v in value.items()
                               if v is not None) + "}"
    return '""'


def _toml_string(text: str) -> str:
    out = []
    for c in text:
        if c in '"\\':
            out.append("\\" + c)
        elif ord(c) < 0x20 or ord(c) == 0x7F:
            out.append(f"\\u{ord(c):04x}")
        else:
            out.append(c)  # a lone surrogate stays: its bytes are no UTF-8
    return '"' + "".join(out) + '"'


def _encode(text: str) -> bytes:
    return text.encode("utf-8", errors="surrogatepass")


def _byte_mutations(data: bytes, rng: random.Random) -> tuple[bytes, list[str]]:
    buf = bytearray(data)
    done = []
    for _ in range(rng.choice((1, 1, 2))):
        n = len(buf)
        if n == 0:
            break
        pos = rng.randrange(n)
        how = rng.randrange(5)
        if how == 0:
            buf[pos] ^= 1 << rng.randrange(8)
            done.append(f"bit flip at byte {pos}")
        elif how == 1:
            insert = rng.choice((b"\x00", b"\xff", b"\xef\xbb\xbf", b"[", b"{", b'"', b"\n",
                                 b"\\", b"1e999", b"]]"))
            buf[pos:pos] = insert
            done.append(f"{insert!r} inserted at byte {pos}")
        elif how == 2:
            del buf[pos : pos + 1 + rng.randrange(32)]
            done.append(f"bytes deleted at {pos}")
        elif how == 3:
            del buf[pos:]
            done.append(f"truncated at byte {pos}")
        else:
            chunk = buf[pos : pos + 1 + rng.randrange(64)]
            buf[rng.randrange(n):0] = chunk
            done.append(f"{len(chunk)} bytes repeated from {pos}")
    return bytes(buf), done


# -- seeds -------------------------------------------------------------------------------------

_SPEC_SEEDS = (
    """[data]
file = "data.csv"
time = "time"
max_bytes = 1000000
jitter = 0.01
delimiter = ","
decimal = "."
time_unit = "s"
skip_rows = 0
columns = ["time", "r", "u", 3]

[channels.r]
role = "r"
unit = "m"
limits = [-5.0, 5.0]

[channels.u]
source = "u"
role = "u"
gain = 2.0
offset = 0.1

[channels.y]
role = "y"

[preprocess]
lowpass = 20.0
decimate = 2
detrend = "mean"

[split]
fraction = 0.5
""",
    """[data]
file = "data.csv"
format = "csv"
skip_columns = ["r"]

[channels.u]
role = "u"

[channels.y_out]
source = "y"
role = "y"
unit = "V"

[split]
index = 40
period = 10
skip_periods = 1

[identify]
method = "arx"
na = 2
orders = {na = [1, 2], nb = [1, 2]}

[report]
folder = "out"
truth = "truth.json"

[loop]
controller = "P"
kp = 2.5
""",
    """[data]
file = ["data.csv", "data2.csv"]

[channels]
u = { role = "u" }
y = { role = "y", limits = [-9.0, 9.0] }

[validation]
file = ["data3.csv"]
initial = "zero"
transient = 3

[rig]
anti_alias = {order = 4, cutoff = 200.0}
reference = "readback"
""",
    """[data]
file = "data.tdms"
group = "servoid"
dt = 0.001

[channels.y]
source = "servoid/y"
role = "y"

[channels.u]
source = "servoid/u"
role = "u"

[rig]
reference = "command"
""",
    """[data]
file = "run.mat"
format = "mat"
time = "run.t"

[channels.y]
source = "run.sig.y"
role = "y"

[channels.u]
source = "run.sig.u"
role = "u"

[preprocess]
detrend = "linear"
""",
)

_FLEET_SEEDS = (
    """[records]
glob = "runs/*.toml"

[identify]
method = "arx"
na = 2
nb = 2
nk = 1

[limits.a1]
nominal = -0.8
tolerance = 0.1

[limits.b0]
min = 0.1
max = 1.0

[trend]
by = "order"

[report]
folder = "fleet-out"
""",
    """[records]
manifest = "units.csv"

[limits.a1]
nominal = -0.8
tolerance_percent = 20.0

[trend]
by = "date"
""",
)

_FLEET_MANIFEST = "path,serial,date\nruns/a.toml,SN-1,2026-01-02\nruns/b.toml,SN-2,2026-01-03\n"
_RUN_TOML = ('[data]\nfile = "../{record}"\ntime = "time"\n[channels.u]\nrole = "u"\n'
             '[channels.y]\nrole = "y"\n[identify]\nmethod = "arx"\n')


def _data_csv(shift: int = 0) -> bytes:
    rows = ["time [s],r [m],u [V],y [m]"]
    y = 0.0
    for k in range(80):
        r = 1.0 if ((k + shift) // 8) % 2 else -1.0
        u = r - 0.3 * y
        y = 0.8 * y + 0.5 * u
        rows.append(f"{k * 0.01!r},{r!r},{u!r},{y!r}")
    return ("\n".join(rows) + "\n").encode()


def seed_names(loader: str) -> tuple[str, ...]:
    """The seed documents of a loader, by name."""
    return tuple(name for name, _ in _seeds(loader))


@cache
def _seeds(loader: str) -> tuple[tuple[str, Any], ...]:
    if loader == "model":
        return tuple((p.stem, json.loads(p.read_text(encoding="utf-8")))
                     for p in sorted((SEEDS / "models").glob("*.json")))
    if loader == "results":
        out = []
        for p in sorted((SEEDS / "results").glob("*.json")):
            if p.name.endswith(".manifest.json"):
                continue
            manifest = json.loads(p.with_suffix(".manifest.json").read_text(encoding="utf-8"))
            out.append((p.stem, {"results": json.loads(p.read_text(encoding="utf-8")),
                                 "manifest": manifest}))
        return tuple(out)
    import tomllib

    texts = _SPEC_SEEDS if loader == "spec" else _FLEET_SEEDS
    return tuple((f"{loader}-{k}", tomllib.loads(t)) for k, t in enumerate(texts))


@cache
def _grammar_of(loader: str) -> _Grammar:
    return _grammar([tree for _, tree in _seeds(loader)])


def _placed(node: Any, folder: str) -> Any:
    """The seed with its @RUN@ and @CODE@ folders put in ``folder``."""
    if isinstance(node, dict):
        return {k: _placed(v, folder) for k, v in node.items()}
    if isinstance(node, list):
        return [_placed(v, folder) for v in node]
    if isinstance(node, str):
        return node.replace("@RUN@", folder).replace("@CODE@", folder)
    return node


# -- inputs ------------------------------------------------------------------------------------


def make_input(loader: str, index: int, folder: Path, seed: int = SEED) -> Input:
    """Input ``index`` of ``loader``; paths in it point into ``folder``."""
    rng = random.Random(f"{seed}:{loader}:{index}")
    seeds = _seeds(loader)
    name, tree = seeds[rng.randrange(len(seeds))]
    tree = _placed(tree, str(folder))  # a new tree: the seed is never changed
    grammar = _grammar_of(loader)
    ops = [f"seed {name}"]
    if loader == "results":  # mutate the results file, its manifest, or both
        target = rng.choice(("results", "results", "results", "manifest", "both"))
        for part in ("results", "manifest"):
            if target in (part, "both"):
                for _ in range(rng.choice((1, 1, 2, 3, 4))):
                    tree[part], done = _mutate(tree[part], grammar, rng)
                    ops.append(f"{part}: {done}")
    else:
        for _ in range(rng.choice((1, 1, 2, 3, 4))):
            tree, done = _mutate(tree, grammar, rng)
            ops.append(done)
    if loader == "model":
        files = {"input.json": _encode(write_json(tree))}
    elif loader == "results":
        files = {"results.json": _encode(write_json(tree["results"])),
                 "manifest.json": _encode(write_json(tree["manifest"]))}
    else:
        files = {"input.toml": _encode(write_toml(tree))}
    if rng.random() < 0.2:
        target = rng.choice(sorted(files))
        files[target], done = _byte_mutations(files[target], rng)
        ops.extend(f"{target}: {d}" for d in done)
    return Input(loader, index, files, rng.randrange(N_MODES[loader]), tuple(ops))


def seed_input(loader: str, name: str, mode: int, folder: Path) -> Input:
    """The seed document ``name`` of ``loader`` unmutated, as an input in call mode ``mode``."""
    tree = _placed(dict(_seeds(loader))[name], str(folder))
    if loader == "model":
        files = {"input.json": _encode(write_json(tree))}
    elif loader == "results":
        files = {"results.json": _encode(write_json(tree["results"])),
                 "manifest.json": _encode(write_json(tree["manifest"]))}
    else:
        files = {"input.toml": _encode(write_toml(tree))}
    return Input(loader, -1, files, mode, (f"seed {name}",))


def prepare(folder: Path) -> None:
    """Write the files the inputs refer to: the grey-box code, records, a fleet's runs."""
    import numpy as np
    import scipy.io

    from servoid.data import Experiment, write_tdms

    code = (SEEDS / "tanks.py").read_bytes()
    if not (folder / "tanks.py").exists():
        (folder / "tanks.py").write_bytes(code)
    for k, name in enumerate(("data.csv", "data2.csv", "data3.csv")):
        (folder / name).write_bytes(_data_csv(k))
    t = 1e-3 * np.arange(60)
    u, y = np.sign(np.sin(40 * t)), np.cos(30 * t)
    write_tdms(Experiment.from_arrays(1e-3, u=u, y=y), folder / "data.tdms", group="servoid",
               overwrite=True)
    scipy.io.savemat(folder / "run.mat", {"run": {"t": t[:, None], "sig": {
        "u": u[:, None], "y": y[:, None]}}})
    runs = folder / "runs"
    runs.mkdir(exist_ok=True)
    for name, record in (("a.toml", "data.csv"), ("b.toml", "data2.csv")):  # two units
        (runs / name).write_text(_RUN_TOML.format(record=record), encoding="utf-8")
    (folder / "units.csv").write_text(_FLEET_MANIFEST, encoding="utf-8")


def run_input(inp: Input, folder: Path) -> str:
    """Write ``inp`` in ``folder`` and call its loader.

    Returns ``"ok"`` or ``"error:<class>"`` for a :class:`ServoidError`;
    any other exception propagates (that is the finding).
    """
    for name, data in inp.files.items():
        (folder / name).write_bytes(data)
    try:
        _CALLS[inp.loader](folder, inp.mode)
    except ServoidError as exc:
        return f"error:{type(exc).__name__}"
    return "ok"


def _model(folder: Path, mode: int) -> None:
    from servoid import load_model

    load_model(folder / "input.json", allow_code=mode == 1)


def _results(folder: Path, mode: int) -> None:
    from servoid.workflows import load_results, rerender
    from servoid.workflows._results import greybox_record

    path = folder / "results.json"
    if mode in (0, 1):
        load_results(path, allow_code=mode == 1)
    elif mode == 2:
        greybox_record(path)
    else:  # the manifest's inputs are never all there: rerender stops before identify
        rerender(path, folder / "again", allow_code=True)


def _spec(folder: Path, mode: int) -> None:
    from servoid.data import load_experiment_spec, write_experiment_spec

    spec = load_experiment_spec(folder / "input.toml")
    if mode == 1:
        spec.records()
    elif mode == 2:
        first = write_experiment_spec(spec, folder / "again.toml", overwrite=True).read_text(
            encoding="utf-8")
        back = load_experiment_spec(folder / "again.toml")
        second = write_experiment_spec(back, folder / "again.toml", overwrite=True).read_text(
            encoding="utf-8")
        if first != second:  # text, not specs: a NaN in a free-form table is not == itself
            raise AssertionError(f"the spec written and read back differs:\n{first}\n{second}")


def _fleet(folder: Path, mode: int) -> None:
    from servoid.fleet import load_fleet_spec

    load_fleet_spec(folder / "input.toml")


_CALLS: dict[str, Callable[[Path, int], None]] = {
    "model": _model, "results": _results, "spec": _spec, "fleet": _fleet,
}
