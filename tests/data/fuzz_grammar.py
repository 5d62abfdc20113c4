"""Grammar-following inputs of the reader fuzzers: files built field by field.

Byte flips (``fuzz_inputs.py``) mostly break a checksum or a tag and stop at
the first check. These generators build each format from its grammar, with
every field drawn from the values that matter, so the inputs reach deep
into each reader and the libraries under it:

* ``csv``: dialects as loggers and spreadsheets write them: delimiter,
  decimal mark, quoting, line ends, byte-order marks, encodings (UTF-16,
  UTF-32, Latin-1), a preamble, comment and blank lines, units in the
  header, a text column, trailing delimiters, numbers spelled every way a
  parser may or may not accept (``1_000``, ``1e``, ``nan``, full-width
  digits), time in seconds, milliseconds or integer ticks, ragged rows,
  long cells, a missing last line end;
* ``tdms``: segments written by hand: lead-in (ToC flags, version, next
  segment and raw-data offsets), object paths, raw-data indexes (new,
  "same as before", none, strings with their byte count), data types,
  value counts, properties of every type code (``wf_increment`` of
  ``5e-324``, ``1e308``, NaN, text, an integer) and raw data, in one to
  three segments (interleaved, big-endian, incomplete);
* ``mat5``: variables of every class and shape written by scipy (plain or
  compressed), then one to three of their fields (element tags, array
  flags, class, dimensions, name, data type and byte count) set to values
  that matter, inside the compressed stream too;
* ``mat73``: HDF5 files built with h5py: ``MATLAB_class`` and
  ``MATLAB_empty`` attributes of every type, shape and size, datasets of
  every dtype, layout and fill value (unwritten storage), soft, external
  and cyclic links, references, struct groups; then perhaps one address
  of the file swapped for another (a B-tree or heap pointing elsewhere).

Every input is ``grammar_input(fmt, random.Random(key))``: the same key
builds the same file, so any input can be rebuilt from its index.
"""

from __future__ import annotations

import io
import math
import random
import struct
import tempfile
import zlib
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["GRAMMARS", "grammar_input", "read_grammar"]

#: Formats with a grammar generator, and the reader format (``fuzz_inputs.FORMATS``) of each.
GRAMMARS = {"csv": "csv", "tdms": "tdms", "mat5": "mat5", "mat73": "mat73"}


def grammar_input(fmt: str, rng: random.Random, *,
                  faults: bool = True) -> tuple[bytes, dict[str, Any]]:
    """A file of ``fmt`` built from its grammar, and the reader keywords that fit it.

    About half the files carry one planted fault (a field set to a value
    that matters, or keywords that do not fit); the others are valid in a
    random dialect, so that the reader gets past its first checks. The
    keywords are those a user would pass for the dialect (delimiter, group,
    variables, time). ``faults=False`` builds valid files only.
    """
    build = {"csv": _csv, "tdms": _tdms, "mat5": _mat5, "mat73": _mat73}[fmt]
    return build(_Draws(rng, faults))


def read_grammar(fmt: str, data: bytes, kwargs: dict[str, Any], folder: Path) -> str:
    """Write ``data`` in ``folder`` and read it with the reader of ``fmt`` and ``kwargs``.

    Returns ``"ok"`` or ``"error:<class>"`` for a :class:`ServoidError`; any
    other exception propagates.
    """
    from servoid import ServoidError
    from servoid.data import read_csv, read_mat, read_tdms

    reader = {"csv": read_csv, "tdms": read_tdms, "mat5": read_mat, "mat73": read_mat}[fmt]
    path = folder / ("input.csv" if fmt == "csv" else "input.tdms" if fmt == "tdms" else
                     "input.mat")
    path.write_bytes(data)
    try:
        reader(path, **kwargs)
    except ServoidError as exc:
        return f"error:{type(exc).__name__}"
    return "ok"


class _Draws(random.Random):
    """The generator's random draws, and whether a fault may be planted."""

    def __init__(self, rng: random.Random, faults: bool) -> None:
        super().__init__()
        self.setstate(rng.getstate())
        self.faults = faults


def _fault(rng: random.Random, faults: tuple[str, ...]) -> str | None:
    """One planted fault of ``faults`` for about half the files, else None."""
    if rng.random() < 0.5 and getattr(rng, "faults", True):
        return rng.choice(faults)
    return None


# -- CSV -------------------------------------------------------------------------------------------

_NUMBER_SPELLINGS = ("{!r}", "{:.6f}", "{:.3e}", "{:g}", "{:.17g}", "{:+.2f}", " {!r} ",
                     '"{!r}"')
_ODD_CELLS = ("", "nan", "NaN", "inf", "-inf", "1_000", "1e", "1.", ".5", "+", "-", "0x10",
              "\uff11\uff12", "\u0661\u0662", "1e309", "1e-400", "\ufeff1.0", "1,5", "1 000",
              '"', '""', "\x00", "abc", "1e5\x00", "9" * 400, "1.0.0", "--1", "١")
_CSV_FAULTS = ("encoding", "bom-inside", "odd-cell", "ragged", "long-cell", "odd-header",
               "no-last-newline", "preamble-unskipped", "ms", "ns", "jitter", "repeat",
               "backwards", "wrong-delimiter", "wrong-decimal", "no-time", "few-rows")


def _csv(rng: random.Random) -> tuple[bytes, dict[str, Any]]:
    fault = _fault(rng, _CSV_FAULTS)
    delimiter = rng.choice((",", ",", ",", ";", "\t", " ", "|"))
    decimal = "," if delimiter != "," and rng.random() < 0.3 else "."
    n = rng.choice((0, 1, 2, 3)) if fault == "few-rows" else rng.choice((5, 20, 60, 250))
    unit = rng.choice(("", " [s]", " [s]", " [ms]", " [us]", " [µs]")) if fault is None else \
        rng.choice(("", " [s]", " [h]", " []", " [s"))
    scale = {"": 1.0, " [s]": 1.0, " [ms]": 1e3, " [us]": 1e6, " [µs]": 1e6}.get(unit, 1.0)
    step = {"ms": 1.0, "ns": 1e6}.get(fault or "", 1e-3 * scale)
    t = np.arange(n) * step
    if fault == "jitter":
        t = t + np.array([rng.uniform(-0.01, 0.01) * step for _ in range(n)])
    elif fault == "repeat" and n > 3:
        t[n // 2] = t[n // 2 - 1]
    elif fault == "backwards":
        t = t[::-1].copy()
    names = [] if fault == "no-time" else ["time" + unit]
    names += [rng.choice(("u [V]", "u", "u [A]")), "y [m]"]
    status = rng.random() < 0.4
    if status:
        names.insert(rng.randrange(1, len(names) + 1), "status")
    if rng.random() < 0.3:
        names.append("r [m]")
    if fault == "odd-header":
        names[rng.randrange(len(names))] = rng.choice(("", "1.5", "#c", "u", '"q"uote', "a\x00"))
    elif fault == "long-cell":
        names[rng.randrange(len(names))] = "x" * rng.choice((300, 140_000))
    quote = rng.random() < 0.15
    trailing = rng.random() < 0.1  # a delimiter at the end of every line, as loggers write
    preamble = [rng.choice(("DL-7 logger", "operator: me", "samples: 25", "rig 7"))
                for _ in range(rng.choice((0, 0, 1, 3)))]
    if delimiter == " ":  # a space-separated file writes names and units without spaces
        names = [h.replace(" ", "") for h in names]
    lines = [*preamble, delimiter.join(f'"{h}"' if quote else h for h in names)
             + (delimiter if trailing else "")]
    spell = rng.choice([s for s in _NUMBER_SPELLINGS if delimiter != " " or " " not in s])
    odd_row = rng.randrange(max(n, 1))
    for k in range(n):
        cells = []
        for name in names:
            if name.startswith("time"):
                exact = fault in ("ms", "ns") and rng.random() < 0.8
                text = str(int(t[k])) if exact else repr(float(t[k]))  # stamps at full precision
            elif name == "status":
                text = rng.choice(("OK", "WARN", "1", ""))
            else:
                text = spell.format(math.sin(k / 7.0 + len(name)))
            if decimal == ",":
                text = text.replace(".", ",")
            cells.append(text)
        if k == odd_row and fault == "odd-cell":
            cells[rng.randrange(len(cells))] = rng.choice(_ODD_CELLS)
        if k == odd_row and fault == "ragged":
            cells = cells[: rng.randrange(len(cells))] if rng.random() < 0.5 else [*cells, "0"]
        if k == odd_row and fault == "bom-inside":
            cells[0] = "\ufeff" + cells[0]
        lines.append(delimiter.join(cells) + (delimiter if trailing else ""))
        if rng.random() < 0.02:
            lines.append(rng.choice(("", "# note", "   ")))
    end = rng.choice(("\n", "\n", "\r\n", "\r"))
    text = end.join(lines) + ("" if fault == "no-last-newline" else end)
    if rng.random() < 0.1:
        text = "\ufeff" + text  # a leading byte-order mark: valid, dropped
    encoding = rng.choice(("utf-16", "utf-16-le", "utf-16-be", "utf-32", "latin-1")) \
        if fault == "encoding" else "utf-8"
    try:
        data = text.encode(encoding)
    except UnicodeEncodeError:
        data = text.encode("utf-8")
    kwargs: dict[str, Any] = {}
    if delimiter != ",":
        kwargs["delimiter"] = delimiter
    if fault == "wrong-delimiter":
        kwargs["delimiter"] = rng.choice((",", ";", "\t", "narx", '"'))
    if decimal == "," or fault == "wrong-decimal":
        kwargs["decimal"] = "," if fault != "wrong-decimal" else rng.choice((",", ".", "x"))
    if preamble and fault != "preamble-unskipped":
        kwargs["skip_rows"] = len(preamble)
    if status:
        kwargs["skip_columns"] = ["status"]
    if fault in ("ms", "ns") and rng.random() < 0.5:
        kwargs["time_unit"] = "ms" if fault == "ms" else rng.choice(("us", "ns"))
    if fault == "no-time" or rng.random() < 0.1:
        kwargs.update(time=None, dt=1e-3)
    if rng.random() < 0.3:
        kwargs["roles"] = {"u": ["u"], "y": ["y"]}
    return data, kwargs


# -- TDMS ------------------------------------------------------------------------------------------

_TDS_TYPES = {"i8": 1, "i16": 2, "i32": 3, "i64": 4, "u8": 5, "u16": 6, "u32": 7, "u64": 8,
              "f4": 9, "f8": 10, "str": 0x20, "bool": 0x21, "time": 0x44}
_NUMPY = {"i8": "i1", "i16": "i2", "i32": "i4", "i64": "i8", "u8": "u1", "u16": "u2",
          "u32": "u4", "u64": "u8", "f4": "f4", "f8": "f8"}
_TOC_META, _TOC_NEW_OBJ, _TOC_RAW, _TOC_INTERLEAVED, _TOC_BIG = 1 << 1, 1 << 2, 1 << 3, \
    1 << 5, 1 << 6
_TIMING = (1e-3, 1e-3, 1e-3, 0.0, -1.0, 5e-324, 1e308, 1e-300, float("nan"), float("inf"),
           "0.001", 1, 10**18)


def _tds_string(text: str, order: str) -> bytes:
    raw = text.encode("utf-8", errors="replace")
    return struct.pack(order + "I", len(raw)) + raw


def _tds_property(name: str, value: object, order: str) -> bytes:
    out = _tds_string(name, order)
    if isinstance(value, str):
        return out + struct.pack(order + "I", 0x20) + _tds_string(value, order)
    if isinstance(value, bool):
        return out + struct.pack(order + "IB", 0x21, value)
    if isinstance(value, int):
        if -(2**63) <= value < 2**63:
            return out + struct.pack(order + "Iq", 4, value)
        return out + struct.pack(order + "IQ", 8, value % 2**64)
    return out + struct.pack(order + "Id", 10, float(value))


def _tds_values(kind: str, n: int, rng: random.Random, order: str) -> bytes:
    if kind == "str":  # the end offset of each string, then the strings
        raw = [rng.choice(("a", "bc", "", "µ")).encode() for _ in range(n)]
        ends = np.cumsum([len(r) for r in raw], dtype=np.int64)
        return b"".join(struct.pack(order + "I", int(e)) for e in ends) + b"".join(raw)
    if kind == "time":
        return b"".join(struct.pack(order + "Qq", rng.getrandbits(64), rng.randrange(2**40))
                        for _ in range(n))
    if kind == "bool":
        return bytes(rng.randrange(2) for _ in range(n))
    dtype = np.dtype(_NUMPY[kind]).newbyteorder(order)
    values = np.sin(np.arange(n) / 5.0) * (100 if dtype.kind in "iu" else 1)
    if dtype.kind == "u":
        values = np.abs(values)
    if kind in ("i64", "u64") and rng.random() < 0.5:
        values = np.arange(n) * 1_000_000  # integer ticks
    return values.astype(dtype).tobytes()


_TDMS_FAULTS = ("timing", "count", "dimension", "same-index", "interleaved", "big-endian",
                "short-raw", "next-offset", "raw-offset", "version", "string-channel",
                "ticks", "property-type")


def _tdms(rng: random.Random) -> tuple[bytes, dict[str, Any]]:
    fault = _fault(rng, _TDMS_FAULTS)
    order = ">" if fault == "big-endian" else "<"
    channels = []
    groups = rng.sample(("servoid", "other", "g"), rng.choice((1, 1, 2)))
    for group in groups:
        for name in rng.sample(("u", "y", "t", "r"), rng.randrange(1, 4)):
            kind = "f8" if rng.random() < 0.7 else rng.choice(("f4", "i32", "i16", "u8"))
            channels.append((group, name, kind))
    if fault == "string-channel":
        channels.append((groups[0], "note", rng.choice(("str", "bool", "time"))))
    if fault == "ticks":
        channels.append((groups[0], "clock", rng.choice(("i64", "u64"))))
    bad = rng.randrange(len(channels))  # the channel a fault of one channel hits
    n = rng.choice((2, 10, 40, 100))
    timing: dict[str, object] = {"wf_increment": 1e-3, "wf_start_offset": 0.0}
    if fault == "timing":
        timing[rng.choice(("wf_increment", "wf_start_offset"))] = rng.choice(_TIMING)
    segments = []
    for seg in range(rng.choice((1, 1, 2, 3))):
        toc = _TOC_RAW | (_TOC_META | _TOC_NEW_OBJ if seg == 0 or rng.random() < 0.3 else 0)
        if fault == "interleaved":
            toc |= _TOC_INTERLEAVED
        if fault == "big-endian":
            toc |= _TOC_BIG
        meta = b""
        values = [_tds_values(kind, n, rng, order) for _, _, kind in channels]
        if toc & _TOC_META:
            objects = [_tds_string("/", order) + struct.pack(order + "II", 0xFFFFFFFF, 1)
                       + _tds_property("name", "run", order)]
            for group in groups:
                props = [("operator", "me")] if rng.random() < 0.5 else []
                objects.append(_tds_string(f"/'{group}'", order)
                               + struct.pack(order + "II", 0xFFFFFFFF, len(props))
                               + b"".join(_tds_property(k, v, order) for k, v in props))
            for k, ((group, name, kind), raw_values) in enumerate(
                    zip(channels, values, strict=True)):
                hit = k == bad
                count = rng.choice((0, n + 1, 2**40, 2**63)) if hit and fault == "count" else n
                dimension = rng.choice((0, 2, 2**31)) if hit and fault == "dimension" else 1
                if seg and (fault == "same-index" or rng.random() < 0.3):
                    index = struct.pack(order + "I", 0)  # as in the previous segment
                elif kind == "str":
                    index = struct.pack(order + "IIIQQ", 28, _TDS_TYPES[kind], dimension, count,
                                        len(raw_values))
                else:
                    index = struct.pack(order + "IIIQ", 20, _TDS_TYPES[kind], dimension, count)
                props: list[tuple[str, object]] = [*timing.items(), ("unit_string", "V")]
                if hit and fault == "property-type":
                    props.append((rng.choice(("wf_increment", "unit_string", "servoid_role")),
                                  rng.choice((1, True, "x", float("nan"), 2**64 - 1))))
                objects.append(_tds_string(f"/'{group}'/'{name}'", order) + index
                               + struct.pack(order + "I", len(props))
                               + b"".join(_tds_property(k, v, order) for k, v in props))
            meta = struct.pack(order + "I", len(objects)) + b"".join(objects)
        raw = b"".join(values)
        if fault == "short-raw" and seg == 0:
            raw = raw[: rng.randrange(len(raw) + 1)]
        next_offset, raw_offset = len(meta) + len(raw), len(meta)
        if fault == "next-offset" and rng.random() < 0.7:
            next_offset = rng.choice((0, 2**64 - 1, next_offset + 8, next_offset // 2))
        if fault == "raw-offset" and rng.random() < 0.7:
            raw_offset = rng.choice((0, raw_offset + 4, 2**63, next_offset + 1))
        version = rng.choice((4712, 0, 1, 2**32 - 1)) if fault == "version" else 4713
        lead = b"TDSm" + struct.pack("<I", toc) + struct.pack(order + "IQQ", version,
                                                              next_offset, raw_offset)
        segments.append(lead + meta + raw)
    kwargs: dict[str, Any] = {}
    names = [c[1] for c in channels if c[0] == groups[0] and c[2] not in ("str", "time")]
    if len(groups) > 1 or rng.random() < 0.2:
        kwargs["group"] = groups[0]
    if rng.random() < 0.3 and names:
        kwargs["channels"] = [f"{groups[0]}/{names[0]}", *names[1:]]
    if fault == "ticks" and rng.random() < 0.7:
        kwargs["time"] = "clock"
        if rng.random() < 0.5:
            kwargs["time_unit"] = rng.choice(("us", "ns"))
    return b"".join(segments), kwargs


# -- MAT v5: fields of the element tree ----------------------------------------------------------


def _mat5_variables(rng: random.Random) -> tuple[dict[str, object], bool]:
    """Variables of every class and shape; whether ``t`` holds integer ticks."""
    import scipy.sparse

    n = rng.choice((2, 5, 30, 200))
    t = 1e-3 * np.arange(n)
    ticks = rng.random() < 0.15
    pool: dict[str, object] = {
        "t": (np.arange(n, dtype=np.int64) * 10**6)[:, None] if ticks else t[:, None],
        "qm": np.sin(t)[:, None].astype(rng.choice((np.float64, np.float32, np.int16))),
        "vir": (0.1 * t)[None, :],
        "kp": rng.choice((160.18, 3, np.int8(4), True)),
        "label": rng.choice(("rig 7", "", "µ" * 3)),
        "K": np.arange(6.0).reshape(2, 3),
        "z": np.array([1 + 2j, 3 - 1j]),
        "cells": np.array([[1.0, "a"]], dtype=object),
        "run": {"sig": {"u": np.cos(t)[:, None], "y": np.sin(t)[None, :]}, "fs": 1e3},
        "sp": scipy.sparse.eye(3, format="csc"),
        "flag": np.arange(n) % 2 == 0,
        "empty": np.zeros((0, 0)),
        "cube": np.ones((2, 2, 2)),
    }
    keep = {"t", "qm", "vir", "run"} | set(rng.sample(sorted(pool), rng.randrange(len(pool))))
    return {k: v for k, v in pool.items() if k in keep}, ticks


def _fields(body: bytes, order: str, base: int, out: list[tuple[int, int, str]]) -> None:
    """Record the fields of a matrix element's body (tags, flags, dims, name, data)."""
    pos = 0
    index = 0
    while pos + 8 <= len(body) and index < 16:
        first = struct.unpack_from(order + "I", body, pos)[0]
        if first >> 16:  # a small element
            out.append((base + pos, 4, "small-tag"))
            pos += 8
        else:
            mdtype, count = struct.unpack_from(order + "2I", body, pos)
            out.append((base + pos, 4, "type"))
            out.append((base + pos + 4, 4, "count"))
            if index == 0 and count == 8:  # array flags: class byte, flag byte, nzmax
                out.append((base + pos + 8, 1, "class"))
                out.append((base + pos + 9, 1, "flags"))
            elif index == 1 and mdtype in (5, 6):  # dimensions
                for k in range(min(count // 4, 4)):
                    out.append((base + pos + 8 + 4 * k, 4, "dim"))
            elif mdtype == 14 and count <= len(body) - pos - 8:  # a nested matrix (field, cell)
                _fields(body[pos + 8: pos + 8 + count], order, base + pos + 8, out)
            pos += 8 + count + (-count % 8)
        index += 1


_FIELD_VALUES = {
    "type": (0, 1, 2, 5, 6, 7, 9, 11, 12, 13, 14, 15, 16, 17, 18, 19, 255, 0xFFFF),
    "count": (0, 1, 4, 7, 8, 9, 16, 4096, 2**31 - 1, 2**31, 2**32 - 1),
    "class": tuple(range(20)),
    "flags": (0, 1 << 1, 1 << 2, 1 << 3, 0xFF),
    "dim": (0, 1, 2, 3, 30, 2**31 - 1, 2**32 - 1, 2**32 - 2, 100_000),
    "small-tag": (0, 0x00010001, 0x00040005, 0x00050009, 0x00080005, 0xFFFF0001),
}


def _mat5(rng: random.Random) -> tuple[bytes, dict[str, Any]]:
    import scipy.io

    buf = io.BytesIO()
    compress = rng.random() < 0.5
    variables, ticks = _mat5_variables(rng)
    scipy.io.savemat(buf, variables, do_compression=compress)
    data = bytearray(buf.getvalue())
    elements = []
    pos = 128
    while pos + 8 <= len(data):
        mdtype, count = struct.unpack_from("<2I", data, pos)
        elements.append((pos, mdtype, count))
        pos += 8 + count
    out = bytearray(data[:128])
    fault = _fault(rng, ("fields", "fields", "fields", "call"))
    targets = {rng.randrange(len(elements)) for _ in range(rng.choice((1, 1, 2)))} \
        if elements and fault == "fields" else set()
    for k, (start, mdtype, count) in enumerate(elements):
        body = bytes(data[start + 8: start + 8 + count])
        if k in targets:
            if mdtype == 15:  # the fields of the inflated element: its tag, then its body
                inflated = zlib.decompress(body)
                fields: list[tuple[int, int, str]] = [(0, 4, "type"), (4, 4, "count")]
                _fields(inflated[8:], "<", 8, fields)
            else:
                inflated = body
                fields = []
                _fields(inflated, "<", 0, fields)
            mutable = bytearray(inflated)
            for _ in range(rng.choice((1, 1, 2))):
                if not fields:
                    break
                at, width, kind = rng.choice(fields)
                value = rng.choice(_FIELD_VALUES[kind])
                if kind == "dim" and rng.random() < 0.3:
                    value = (-value) % 2**32
                mutable[at: at + width] = (value % 256**width).to_bytes(width, "little")
            body = zlib.compress(bytes(mutable)) if mdtype == 15 else bytes(mutable)
            if rng.random() < 0.1:  # an outer count that does not fit either
                out += struct.pack("<2I", mdtype, rng.choice((0, len(body) + 8, 2**31)))
                out += body
                continue
        out += struct.pack("<2I", mdtype, len(body)) + body
    return bytes(out), _mat_call(rng, ticks, odd=fault == "call")


def _mat_call(rng: random.Random, ticks: bool, odd: bool = False) -> dict[str, Any]:
    """Reader keywords for the MAT files built here (variables t, qm, vir, run.sig.u/y).

    ``odd``: variables that are not vectors, or not there.
    """
    choice = 3 if odd else rng.randrange(3)
    if choice == 0:
        return {"dt": 1e-3}
    if choice == 1:
        call: dict[str, Any] = {"variables": ["qm", "vir"], "time": "t"}
        if ticks and (rng.random() < 0.6 or not getattr(rng, "faults", True)):
            call["time_unit"] = "ns"
        return call
    if choice == 2:
        return {"variables": ["run.sig.u", "run.sig.y"], "dt": 1e-3,
                "roles": {"y": ["run.sig.y"]}}
    return {"variables": rng.sample(("qm", "vir", "t", "kp", "label", "K", "z", "cells", "sp",
                                     "run", "run.fs", "run.sig", "nope", "x"), 2), "dt": 1e-3}


# -- MAT v7.3: HDF5 attributes, datasets, links ------------------------------------------------


def _attr(rng: random.Random) -> object:
    import h5py

    choice = rng.randrange(10)
    if choice < 4:
        return np.bytes_(rng.choice(("double", "char", "cell", "struct", "logical", "int64",
                                     "single", "uint16", "function_handle", "")))
    return (
        np.bytes_("double" * rng.choice((1, 100, 3000))),
        np.array([b"double", b"char"]),
        rng.choice(("double", "char")),  # a variable-length string
        np.uint8(rng.randrange(3)),
        np.array([1, 2, 3], dtype=np.uint64),
        h5py.Empty("f8"),
    )[choice - 4]


_DATASET_KINDS = ("scalar", "matrix", "empty", "unwritten", "chunked", "compound", "vlen",
                  "int64", "char", "reference", "cube")
_MAT73_FAULTS = ("dataset", "attribute", "link", "address", "ticks", "struct")


def _dataset(group: Any, name: str, n: int, rng: random.Random, kind: str = "vector") -> None:
    """A dataset as MATLAB writes a variable of ``kind`` (or a hostile one)."""
    import h5py

    if kind == "vector":
        data = (1e-3 * np.arange(n) if name == "t" else np.sin(np.arange(n) / 3.0 + len(name)))[
            None, :]
        ds = group.create_dataset(name, data=data, **(
            {"chunks": (1, max(1, n // 3)), "compression": "gzip"} if rng.random() < 0.3
            else {}))
    elif kind == "scalar":
        ds = group.create_dataset(name, data=np.array([[rng.random()]]))
    elif kind == "matrix":
        ds = group.create_dataset(name, data=np.ones((3, n)))
    elif kind == "cube":
        ds = group.create_dataset(name, data=np.ones((2, 2, n)))
    elif kind == "empty":
        ds = group.create_dataset(name, data=np.array([0, 0], dtype=np.uint64))
        ds.attrs["MATLAB_empty"] = np.uint8(1)
    elif kind == "unwritten":
        ds = group.create_dataset(name, shape=(1, rng.choice((n, 2**24, 2**28))), dtype="f8",
                                  fillvalue=rng.choice((0.0, 1.5, float("nan"))))
    elif kind == "chunked":
        ds = group.create_dataset(name, shape=(1, n), dtype="f8",
                                  chunks=(1, min(n, rng.choice((1, 7, 64)))),
                                  compression=rng.choice(("gzip", "lzf", None)),
                                  shuffle=rng.random() < 0.5)
        if rng.random() < 0.5:
            ds[0, : n // 2] = 1.0  # some chunks written, the rest fill value
    elif kind == "compound":
        ds = group.create_dataset(name, data=np.zeros((1, n), dtype=[("re", "f8"), ("im", "f8")]))
    elif kind == "vlen":
        ds = group.create_dataset(name, data=np.array([["a", "bc"]], dtype=object),
                                  dtype=h5py.string_dtype())
    elif kind == "int64":
        ds = group.create_dataset(name, data=(np.arange(n, dtype=np.int64) * 10**6)[None, :])
        ds.attrs["MATLAB_class"] = np.bytes_("int64")
    elif kind == "char":
        ds = group.create_dataset(name, data=np.frombuffer(b"rig 7", np.uint8).astype(
            np.uint16)[:, None])
        ds.attrs["MATLAB_class"] = np.bytes_("char")
    else:  # a cell: references into #refs#
        refs = group.file.require_group("#refs#")
        target = refs.create_dataset(f"r{len(refs)}", data=np.ones((1, n)))
        ds = group.create_dataset(name, data=np.array([[target.ref]]), dtype=h5py.ref_dtype)
        ds.attrs["MATLAB_class"] = np.bytes_("cell")
    if "MATLAB_class" not in ds.attrs:
        ds.attrs["MATLAB_class"] = np.bytes_("double")


def _attr(rng: random.Random) -> object:
    """A MATLAB_class or MATLAB_empty attribute of some type, shape and size."""
    import h5py

    return rng.choice((
        np.bytes_(rng.choice(("double", "char", "cell", "struct", "logical", "int64", "single",
                              "uint16", "function_handle", ""))),
        np.bytes_("double" * rng.choice((100, 3000))),
        np.array([b"double", b"char"]),
        "double",  # a variable-length string
        np.uint8(rng.randrange(3)),
        np.array([1, 2, 3], dtype=np.uint64),
        h5py.Empty("f8"),
        np.zeros(20_000),
    ))


def _mat73(rng: random.Random) -> tuple[bytes, dict[str, Any]]:
    import h5py

    fault = _fault(rng, _MAT73_FAULTS)
    n = rng.choice((2, 5, 30, 200))
    with tempfile.TemporaryDirectory(prefix="servoid-grammar-") as folder:
        path = Path(folder) / "a.mat"
        with h5py.File(path, "w", userblock_size=512,
                       libver=rng.choice(("earliest", "earliest", "latest"))) as f:
            names = ["t", "qm", "vir", *rng.sample(("kp", "label", "K", "x"), rng.randrange(3))]
            odd = rng.choice(names)
            for name in names:
                kind = {"kp": "scalar", "label": "char", "K": "matrix"}.get(name, "vector")
                if fault == "dataset" and name == odd:
                    kind = rng.choice(_DATASET_KINDS)
                if fault == "ticks" and name == "t":
                    kind = "int64"
                _dataset(f, name, n, rng, kind)
                if fault == "attribute" and name == odd:
                    try:
                        f[name].attrs[rng.choice(("MATLAB_class", "MATLAB_empty"))] = _attr(rng)
                    except (OSError, TypeError, ValueError):  # too large for the header
                        pass
            run = f.create_group("run")
            run.attrs["MATLAB_class"] = np.bytes_("struct")
            sig = run.create_group("sig")
            sig.attrs["MATLAB_class"] = np.bytes_("struct")
            for name in ("u", "y"):
                _dataset(sig, name, n, rng)
            if fault == "struct":
                choice = rng.randrange(4)
                if choice == 0:
                    sig["loop"] = h5py.SoftLink("/run")  # a cycle through a soft link
                elif choice == 1:
                    run["again"] = run  # a cycle through a hard link
                elif choice == 2:
                    _dataset(run, "arr", n, rng, "reference")  # a struct array's field
                else:
                    del sig["y"]
                    _dataset(sig, "y", n, rng, rng.choice(_DATASET_KINDS))
            if fault == "link":
                name = rng.choice(("ext", "far", "run/sig/z"))
                f[name] = rng.choice((
                    h5py.SoftLink("/" + rng.choice(("t", "run", "#refs#", "nowhere"))),
                    h5py.ExternalLink(rng.choice(("/etc/hostname", "b.mat", "../x.mat",
                                                  "a.mat")), "/t"),
                ))
                if "/" not in name and rng.random() < 0.5:
                    odd = name
        with path.open("r+b") as fh:
            fh.write(b"MATLAB 7.3 MAT-file, Platform: GLNXA64".ljust(128, b" "))
        data = bytearray(path.read_bytes())
    if fault == "address":  # one address of the file pointing elsewhere in it
        size = len(data)
        places = [k for k in range(512, size - 8, 8)
                  if 512 <= struct.unpack_from("<Q", data, k)[0] < size]
        if places:
            values = sorted({struct.unpack_from("<Q", data, k)[0] for k in places})
            at = rng.choice(places)
            data[at: at + 8] = struct.pack("<Q", rng.choice(values) + rng.choice(
                (0, 0, -8, 8, -16, 16, -24, 24)))
    call = _mat_call(rng, fault == "ticks")
    if fault in ("dataset", "attribute", "link") and rng.random() < 0.5:
        call = {"variables": [odd], "dt": 1e-3}
    return bytes(data), call
