"""The figures the docs quote, tied to the commands that print them.

Two markers, in README.md and docs/*.md (an HTML comment: invisible on the rendered page).

An **output block** is what a command prints::

    <!-- output: python examples/flexible_arm.py -->
    ```
    model                                             validation fit  notes
    ARX (na = 4, nb = 4, nk = 1)                              14.9 %      2
    …
    ```

The fenced block right after the marker (or the lines up to ``<!-- end output -->`` when
no fence follows, e.g. a Markdown table) must equal the command's standard output. A line
starting ``$ `` is the prompt a reader sees, not output. A line holding only ``…`` stands
for any number of lines, and ``…`` inside a line for any text (a temporary path). Text
must match exactly; a number may differ by one unit in its last printed digit, because
another BLAS build can round a last digit the other way.

A **numbers** marker ties the figures of the paragraph, list or table that follows it (up
to the next blank line or marker) to a source::

    <!-- numbers: python examples/emps/emps_identify.py -->
    On DATA_EMPS, starting at rest, the position relative error is 0.0015 % …

Every decimal number there (``0.0015``, ``5.76``, ``1.2e-05``) and every whole number
followed by ``%`` must appear in the source's output, rounded as the text rounds it (again
to one unit in the last digit); numbers inside `code` spans and identifiers such as ``b0``
or ``§3.1`` are not figures. Numbers markers on consecutive lines share the text below
them, whose figures may come from any of their sources.

Sources and options
-------------------
``COMMAND`` is ``python FILE [ARGS]`` (this interpreter, with this checkout's ``src`` first
on the path), ``servoid ARGS`` (``python -m servoid``) or ``snippet`` (the last ```python
block above the marker, run as a script); ``A && B`` runs B after A succeeded, in the same
folder, and their outputs follow each other. A numbers marker may instead name
``file PATH``: the figures are written in that file — a benchmark's results JSON, or a test
that asserts them. Options follow the command after `` ; ``:

``in=DIR``
    run inside a fresh copy of the repository's DIR (for commands that read and write
    next to their files). Without it a command runs in an empty temporary folder, its
    arguments that name files of the repository made absolute, and must leave that folder
    empty: examples write into a folder they are given or a temporary one.
``slow``
    run only with ``--slow`` (``pytest -m slow``): a study or a long run.
``timeout=SECONDS``
    default 600.

Each command runs once per process (the examples' test and the docs' test share the run).

Usage::

    python tests/docs_check.py [--update] [--slow] [FILE ...]

checks every marker (``--update`` rewrites output blocks that no longer match; a numbers
marker that fails names the figure and is fixed by hand).
"""

from __future__ import annotations

import argparse
import os
import re
import shlex
import shutil
import subprocess
import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DOCS = (ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md")))

_MARKER = re.compile(r"^\s*<!-- (output|numbers): (.+?) -->\s*$")
_END = "<!-- end output -->"
_ELLIPSIS = "…"
# a number that is a figure: not part of an identifier (b0, S6, p_I), a section (§3.1) or a
# version; the sign may be a Unicode minus
_NUMBER = re.compile(r"(?<![\w.§/^])[-+−]?(?:\d+\.\d+|\d+)(?:[eE][-+−]?\d+)?(?![\w.]*\w)")
_FIGURE = re.compile(r"(?<![\w.§/^])[-+−]?(?:\d+\.\d+(?:[eE][-+−]?\d+)?|\d+[eE][-+−]?\d+|"
                     r"\d+(?=\s?%)(?!\s?%\s*(?:confidence|intervals?|CI)))")
_CODE_SPAN = re.compile(r"`[^`]*`")


# -- markers -------------------------------------------------------------------------------
@dataclass
class Marker:
    """One marker: where it is, its source and options, and the text it governs."""

    path: Path
    line: int  # 1-based line of the marker
    kind: str  # "output" | "numbers"
    source: str
    options: dict[str, str]
    body: list[str]  # the governed lines (an output block without its fences)
    span: tuple[int, int]  # 0-based [start, stop) of `body` in the file's lines
    snippet: str | None = None  # the python block above, for source "snippet"
    also: list[Marker] = field(default_factory=list)  # stacked numbers markers, same text

    @property
    def slow(self) -> bool:
        return "slow" in self.options or any(m.slow for m in self.also)

    @property
    def label(self) -> str:
        sources = " + ".join([self.source, *(m.source for m in self.also)])
        return f"{_shown(self.path)}:{self.line} {sources}"


def _shown(path: Path) -> str:
    return str(path.relative_to(ROOT)) if path.is_relative_to(ROOT) else str(path)


def markers(path: Path) -> list[Marker]:
    """Every marker of a Markdown file, with the lines it governs."""
    lines = path.read_text(encoding="utf-8").splitlines()
    found: list[Marker] = []
    for i, line in enumerate(lines):
        match = _MARKER.match(line)
        if not match:
            continue
        stacked = (found and found[-1].kind == "numbers" and match.group(1) == "numbers"
                   and found[-1].line + len(found[-1].also) == i)
        kind, text = match.groups()
        source, *opts = [part.strip() for part in text.split(" ; ")]
        options = {}
        for opt in opts:
            key, _, value = opt.partition("=")
            options[key.strip()] = value.strip()
        unknown = set(options) - {"in", "slow", "timeout"}
        if unknown:
            raise ValueError(f"{path}:{i + 1}: unknown marker option(s) {sorted(unknown)}")
        if kind == "output":
            start, stop = _output_span(lines, i, path)
        else:
            start = i + 1
            while start < len(lines) and _MARKER.match(lines[start]):
                start += 1  # stacked markers: the text below all of them
            stop = start  # up to a blank line or the next marker
            while stop < len(lines) and lines[stop].strip() and not _MARKER.match(lines[stop]):
                stop += 1
            if stop == start:
                raise ValueError(f"{path}:{i + 1}: a numbers marker must be followed by text")
        snippet = _snippet_above(lines, i) if source == "snippet" else None
        if source == "snippet" and snippet is None:
            raise ValueError(f"{path}:{i + 1}: source 'snippet' needs a ```python block above")
        marker = Marker(path, i + 1, kind, source, options, lines[start:stop], (start, stop),
                        snippet)
        if stacked:
            found[-1].also.append(marker)
        else:
            found.append(marker)
    return found


def _output_span(lines: list[str], i: int, path: Path) -> tuple[int, int]:
    j = i + 1
    if j < len(lines) and lines[j].startswith("```"):
        stop = j + 1
        while stop < len(lines) and not lines[stop].startswith("```"):
            stop += 1
        if stop == len(lines):
            raise ValueError(f"{path}:{i + 1}: the output block is not closed")
        return j + 1, stop
    stop = j
    while stop < len(lines) and lines[stop].strip() != _END:
        stop += 1
    if stop == len(lines):
        raise ValueError(f"{path}:{i + 1}: no fenced block after the marker and no {_END}")
    return j, stop


def _snippet_above(lines: list[str], i: int) -> str | None:
    for end in range(i - 1, -1, -1):
        if lines[end].strip() == "```":
            for start in range(end - 1, -1, -1):
                if lines[start].startswith("```"):
                    if lines[start].strip() == "```python":
                        return "\n".join(lines[start + 1:end]) + "\n"
                    break
            break
    return None


# -- running -------------------------------------------------------------------------------
@dataclass
class Run:
    """What a command did."""

    command: str
    returncode: int
    stdout: str
    stderr: str
    left_in_cwd: list[str] = field(default_factory=list)
    wrote_to_tmp: bool = False  # something appeared in the temporary folder (TMPDIR)


_RUNS: dict[tuple[str, str, str], Run] = {}


def run(source: str, options: dict[str, str] | None = None, snippet: str | None = None) -> Run:
    """Run a marker's command once per process (later calls reuse the run)."""
    options = options or {}
    key = (source, options.get("in", ""), snippet or "")
    if key not in _RUNS:
        _RUNS[key] = _run(source, options, snippet)
    return _RUNS[key]


def _run(source: str, options: dict[str, str], snippet: str | None) -> Run:
    timeout = float(options.get("timeout", 600))
    with tempfile.TemporaryDirectory(prefix="servoid-docs-") as scratch:
        scratch_path = Path(scratch)
        tmp = scratch_path / "tmp"  # TMPDIR: where an example's own temporary folder goes
        tmp.mkdir()
        if "in" in options:
            cwd = _mirror(options["in"], scratch_path / "repo")
        else:
            cwd = scratch_path / "cwd"
            cwd.mkdir()
        env = {**os.environ, "TMPDIR": str(tmp), "MPLBACKEND": "Agg",
               "PYTHONPATH": os.pathsep.join(
                   [str(ROOT / "src"), *filter(None, [os.environ.get("PYTHONPATH")])])}
        stdout, stderr, code = "", "", 0
        for part in _commands(source):  # `a && b`: b runs when a succeeded
            argv = _argv(part, snippet, cwd, absolute="in" not in options)
            done = subprocess.run(argv, cwd=cwd, capture_output=True, text=True, env=env,
                                  timeout=timeout, check=False)
            stdout, stderr, code = stdout + done.stdout, stderr + done.stderr, done.returncode
            if code:
                break
        left = [] if "in" in options else sorted(
            p.name for p in cwd.iterdir() if p.name != "_snippet.py")
        return Run(source, code, stdout, stderr, left, any(tmp.iterdir()))


def _commands(source: str) -> list[str]:
    return [part.strip() for part in source.split(" && ")]


def _mirror(folder: str, mirror: Path) -> Path:
    """A tree like the repository's whose ``folder`` is a fresh copy, the rest linked.

    Relative paths that leave ``folder`` (``../../src/servoid/datasets/…``) still resolve,
    and nothing the command writes reaches the repository.
    """
    parts = Path(folder).parts
    mirror.mkdir()
    for entry in ROOT.iterdir():
        if entry.name not in (parts[0], ".git", ".venv"):
            (mirror / entry.name).symlink_to(entry, target_is_directory=entry.is_dir())
    here, source = mirror, ROOT
    for part in parts[:-1]:  # the path down to `folder`: real folders, siblings linked
        here, source = here / part, source / part
        here.mkdir()
        for entry in source.iterdir():
            if entry.name != parts[len(here.relative_to(mirror).parts)]:
                (here / entry.name).symlink_to(entry, target_is_directory=entry.is_dir())
    target = mirror / folder
    shutil.copytree(ROOT / folder, target, symlinks=True,
                    ignore=shutil.ignore_patterns("__pycache__", "*-results"))
    return target


def _argv(source: str, snippet: str | None, cwd: Path, absolute: bool) -> list[str]:
    if source == "snippet":
        path = cwd / "_snippet.py"
        path.write_text(snippet or "", encoding="utf-8")
        return [sys.executable, str(path)]
    words = shlex.split(source)
    if words[0] == "python":
        argv = [sys.executable, *words[1:]]
    elif words[0] == "servoid":
        argv = [sys.executable, "-m", "servoid", *words[1:]]
    else:
        raise ValueError(f"a command starts with python, servoid or is 'snippet': {source!r}")
    if absolute:
        argv = [str(ROOT / w) if i and not w.startswith("-") and (ROOT / w).exists() else w
                for i, w in enumerate(argv)]
    return argv


# -- comparing -----------------------------------------------------------------------------
def _decimals(token: str) -> tuple[float, float]:
    """A printed number's value and one unit of its last printed digit."""
    text = token.replace("−", "-")
    mantissa, _, exponent = text.lower().partition("e")
    places = len(mantissa.partition(".")[2])
    scale = 10.0 ** (int(exponent) if exponent else 0)
    return float(text), 10.0 ** -places * scale


def _same(doc: str, out: str) -> bool:
    a, unit = _decimals(doc)
    b, _ = _decimals(out)
    if "." not in doc and "e" not in doc.lower():
        return a == b  # a count, an order, a sample index: exact
    return abs(a - b) <= unit * (1 + 1e-9)


def _line_pattern(doc: str) -> tuple[re.Pattern[str], list[str]]:
    parts, numbers, pos = [], [], 0
    for match in _NUMBER.finditer(doc):
        parts.append(_literal(doc[pos:match.start()]))
        parts.append(r"([-+−]?(?:\d+\.\d+|\d+)(?:[eE][-+−]?\d+)?)")
        numbers.append(match.group())
        pos = match.end()
    parts.append(_literal(doc[pos:]))
    return re.compile("".join(parts)), numbers


def _literal(text: str) -> str:
    return ".*?".join(re.escape(piece) for piece in text.split(_ELLIPSIS))


def compare(doc_lines: list[str], output: str) -> str | None:
    """None when the output matches the block; else the first difference, in words."""
    want = [line.rstrip() for line in doc_lines if not line.startswith("$ ")]
    got = [line.rstrip() for line in output.rstrip("\n").splitlines()]
    while want and not want[-1]:
        want.pop()
    problem = _match(want, 0, got, 0)
    return problem


def _match(want: list[str], i: int, got: list[str], j: int) -> str | None:
    while i < len(want):
        if want[i].strip() == _ELLIPSIS:
            if i + 1 == len(want):
                return None
            first = None
            for k in range(j, len(got) + 1):
                problem = _match(want, i + 1, got, k)
                if problem is None:
                    return None
                first = first or problem
            return first
        if j >= len(got):
            return f"the docs show {want[i]!r}, the output ended before it"
        problem = _line(want[i], got[j])
        if problem:
            return problem
        i, j = i + 1, j + 1
    if j < len(got):
        return f"the output goes on: {got[j]!r}"
    return None


def _line(doc: str, out: str) -> str | None:
    pattern, numbers = _line_pattern(doc)
    match = pattern.fullmatch(out)
    if match is None:
        return f"the docs show {doc!r}, the output is {out!r}"
    for want, got in zip(numbers, match.groups(), strict=True):
        if not _same(want, got):
            return f"{want} in {doc!r} is {got} in the output {out!r}"
    return None


def figures(lines: list[str]) -> list[str]:
    """The figures of a paragraph: decimals, and whole numbers before %, outside code."""
    text = _CODE_SPAN.sub(" ", "\n".join(lines))
    return [m.group() for m in _FIGURE.finditer(text)]


def source_numbers(text: str) -> list[str]:
    """Every number a source's text holds."""
    return [m.group() for m in re.finditer(r"[-+−]?(?:\d+\.\d*|\.\d+|\d+)(?:[eE][-+−]?\d+)?",
                                           text)]


def _found(figure: str, numbers: list[float]) -> bool:
    value, unit = _decimals(figure)
    value = abs(value)
    return any(abs(abs(n) - value) <= unit * (1 + 1e-9) for n in numbers)


def missing_figures(marker: Marker, text: str) -> list[str]:
    """The figures of a numbers marker's paragraph that its source does not hold."""
    values = []
    for token in source_numbers(text):
        try:
            values.append(float(token.replace("−", "-")))
        except ValueError:
            continue
    return [f for f in figures(marker.body) if not _found(f, values)]


def source_text(marker: Marker) -> tuple[str, str | None]:
    """A marker's source output (or file text), and what went wrong running it."""
    if marker.source.startswith("file "):
        path = ROOT / marker.source[5:].strip()
        if not path.is_file():
            return "", f"{_shown(path)} does not exist"
        return path.read_text(encoding="utf-8"), None
    done = run(marker.source, marker.options, marker.snippet)
    if done.returncode != 0:
        return done.stdout, (f"{marker.source} failed (exit {done.returncode}):\n"
                             f"{done.stderr[-3000:]}")
    return done.stdout, None


def check(marker: Marker) -> str | None:
    """None when the marker's text agrees with its source; else what differs."""
    text, failure = source_text(marker)
    if failure:
        return failure
    if marker.kind == "output":
        if marker.source.startswith("file "):
            return "an output block needs a command, not a file"
        problem = compare(marker.body, text)
        return None if problem is None else (
            f"{problem}\n(python tests/docs_check.py --update {_shown(marker.path)} rewrites "
            "the block)")
    for other in marker.also:
        more, failure = source_text(other)
        if failure:
            return failure
        text += "\n" + more
    missing = missing_figures(marker, text)
    if missing:
        return (f"not in the output of {marker.source}: {', '.join(missing)} — print them "
                "there, or correct the text")
    return None


def update(path: Path, slow: bool) -> list[str]:
    """Rewrite the output blocks of ``path`` that differ; return what was rewritten."""
    lines = path.read_text(encoding="utf-8").splitlines()
    changed = []
    for marker in reversed(markers(path)):
        if marker.kind != "output" or (marker.slow and not slow) or check(marker) is None:
            continue
        done = run(marker.source, marker.options, marker.snippet)
        prompt = [line for line in marker.body if line.startswith("$ ")]
        new = prompt + [line.rstrip() for line in done.stdout.rstrip("\n").splitlines()]
        start, stop = marker.span
        lines[start:stop] = new
        changed.append(marker.label + (" (it had … elisions: put them back by hand)"
                                       if any(_ELLIPSIS in line for line in marker.body) else ""))
    if changed:
        path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return changed


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="Check (or --update) the docs' quoted figures.")
    parser.add_argument("files", nargs="*", type=Path, help="Markdown files (default: all)")
    parser.add_argument("--update", action="store_true", help="rewrite output blocks that differ")
    parser.add_argument("--slow", action="store_true", help="also run the slow markers")
    args = parser.parse_args(argv)
    paths = [p.resolve() for p in args.files] or list(DOCS)
    failed = 0
    for path in paths:
        if args.update:
            for label in update(path, args.slow):
                print(f"rewrote {label}")
        for marker in markers(path):
            if marker.slow and not args.slow:
                print(f"skipped (slow) {marker.label}")
                continue
            problem = check(marker)
            print(f"{'ok' if problem is None else 'FAILED'} {marker.label}")
            if problem:
                failed += 1
                print("  " + problem.replace("\n", "\n  "))
    return 1 if failed else 0


if __name__ == "__main__":
    raise SystemExit(main())
