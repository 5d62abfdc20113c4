"""Seed files, mutations and reader calls of the reader fuzzers.

Shared by the Hypothesis fuzzers of ``test_data_fuzz.py`` (in process,
derandomized, a few hundred inputs each) and the long run of
``benchmarks/bench_fuzz.py`` (≥ 50 000 inputs in forked batches).

An input is a seed file of one format and a short list of mutations, each
an ``(op, a, b)`` triple of integers, so Hypothesis can draw and shrink it
and a seeded :class:`random.Random` can draw it the same way. The
mutations are byte-level (bit flips, interesting 8/32/64-bit values,
truncation, deletion, duplication, insertion) plus, for text formats,
number and delimiter substitutions, and for compressed MAT v5 files the
same byte mutations applied *inside* one inflated element and compressed
again, so they reach scipy's compiled parser rather than stopping at
zlib's checksum.
"""

from __future__ import annotations

import io
import random
import re
import struct
import tempfile
import zlib
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from functools import cache
from pathlib import Path

import numpy as np

from servoid import Experiment, ServoidError

__all__ = [
    "FORMATS",
    "SUFFIX",
    "Op",
    "mutate",
    "own_seeds",
    "random_ops",
    "read_input",
    "seeds",
]

Op = tuple[int, int, int]
#: Fuzzed formats: mat5z is MAT v5 with compressed elements.
FORMATS = ("csv", "toml", "tdms", "mat4", "mat5", "mat5z", "mat73")
SUFFIX = {"csv": ".csv", "toml": ".toml", "tdms": ".tdms", "mat4": ".mat", "mat5": ".mat",
          "mat5z": ".mat", "mat73": ".mat"}
N_OPS = 11
#: Reader calls per input: the reader's own defaults, named variables / given dt, or the
#: rig-file options (CSV skip_rows and skip_columns, TDMS "group/channel", MAT struct fields).
N_MODES = 3

_BYTES = (0x00, 0x01, 0x7F, 0x80, 0xFF, 0x20, 0x0A, 0x2C, 0x22, 0x09)
_U32 = (
    0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 12, 13, 14, 15, 16, 17, 18, 19, 31, 32, 33, 63, 64, 127, 128,
    255, 256, 1000, 4096, 5000, 5001, 0x7FFF, 0x8000, 0xFFFF, 0x10000, 0x00010001, 0x00040005,
    0x00080005, 0x00050009, 0x7FFFFFFF, 0x80000000, 0xFFFFFFFE, 0xFFFFFFFF, 0x69120000,
    0x69130000,
)
_U64 = (0, 1, 8, 2**31, 2**32, 2**40, 10**12, 2**62, 2**63, 2**64 - 1)
_TEXT_NUMBERS = (
    "0", "-0", "1e308", "1e309", "-1e308", "1e160", "-3e154", "1e-320", "nan", "inf", "-inf",
    "", "1.", ".5", "1e", "1e-0", "0x10", "1_000", "+", "-", "2147483648", "-1",
    "123456789012345678901234567890", "true", '"a"', "[1, 2]", "{}", "1e-6", "100000000",
)
_TEXT_BITS = ("\n", ",", '"', "[", "]", "=", "#", "\x00", "\r", "\ufeff", " ", "'", "\\", ".",
              "[[x]]\n", "\n[data]\n", "$x^2$", "é")
_NUMBER = re.compile(rb"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")

_CSV_DATA = "data.csv"  # the record the TOML seeds name, written beside each TOML input
_TOML_SEEDS = (
    """[data]
file = "data.csv"
time = "time"

[channels.r]
role = "r"
unit = "m"

[channels.u]
source = "u"
role = "u"
gain = 2.0

[channels.y]
role = "y"
limits = [-5.0, 5.0]

[split]
fraction = 0.5
""",
    """[data]
file = "data.csv"
format = "csv"
dt = 0.001

[channels.y_out]
source = "y"
role = "y"
offset = 0.5
unit = "V"

[channels.u]
role = "u"

[preprocess]
lowpass = 100.0
decimate = 2
detrend = "mean"

[split]
index = 20
period = 10
skip_periods = 1

[identify]
models = ["arx"]
na = 2

[report]
folder = "out"
""",
    """[data]
file = ["data.csv", "data.csv"]

[channels.u]
role = "u"

[channels.y]
role = "y"

[validation]
file = "data.csv"
initial = "zero"
transient = 3

[rig]
anti_alias = {order = 4, cutoff = 200.0}
reference = "command"

[loop]
controller = "P"
kp = 2.5
""",
    """[data]
file = "data.csv"
skip_rows = 0
columns = ["u", "y", 0]
delimiter = ","

[channels.u]
source = "u"
role = "u"

[channels.y]
role = "y"
""",
)


def _experiment(n: int = 40) -> Experiment:
    t = np.arange(n)
    return Experiment.from_arrays(
        1e-3,
        r=np.sin(t / 5.0),
        u=np.cos(t / 7.0) * 3.0,
        y=np.sin(t / 3.0) * 1e-3,
        name="seed",
        units={"r": "m", "u": "V", "y": "m"},
    )


def _csv_seeds() -> list[bytes]:
    from servoid.data import write_csv

    exp = _experiment()
    out = []
    with _scratch() as folder:
        path = write_csv(exp, folder / "a.csv")
        out.append(path.read_bytes())
    rows = ["# rig 7, fixed format", "", "time [ms],r [m],u [V],y [m]"]
    rows += [f"{k:.3f},{np.sin(k / 5):.6f},{np.cos(k / 7):.6f},{1e-3 * np.sin(k / 3):.6e}"
             for k in range(30)]
    out.append("\r\n".join(rows).encode())  # CRLF, and no line end at the end
    out.append(b'"time [s]","u [A]"\n' + b"".join(
        f"{k * 0.01!r},{k % 3 - 1}\n".encode() for k in range(20)))
    # a logger's file: a preamble, a text column, a trailing delimiter
    rows = ["DL-7 logger", "samples:,25", "time [s],u [V],status,y [m],"]
    rows += [f"{k * 1e-3!r},{np.cos(k / 7):.6f},{'OK' if k % 4 else 'WARN'},"
             f"{np.sin(k / 3):.6f}," for k in range(25)]
    out.append(("\n".join(rows) + "\n").encode())
    return out


def _tdms_seeds() -> list[bytes]:
    from nptdms import ChannelObject, GroupObject, RootObject, TdmsWriter

    from servoid.data import write_tdms

    exp = _experiment(60)
    out = []
    with _scratch() as folder:
        out.append(write_tdms(exp, folder / "a.tdms").read_bytes())
        path = folder / "b.tdms"
        props = {"wf_increment": 0.002, "wf_start_offset": 1.0, "unit_string": "V"}
        with TdmsWriter(str(path)) as writer:
            for part in range(2):  # two segments, the second without new metadata
                values = np.arange(10.0) + 10 * part
                writer.write_segment([
                    RootObject({"title": "rig"}),
                    GroupObject("servoid", {"operator": "me", "run": 3}),
                    ChannelObject("servoid", "u", values, properties=props),
                    ChannelObject("servoid", "y", values.astype(np.int32), properties=props),
                ])
        out.append(path.read_bytes())
        path = folder / "c.tdms"  # several groups, one channel name in two of them
        with TdmsWriter(str(path)) as writer:
            writer.write_segment([
                RootObject({}),
                GroupObject("servoid", {"card": 1}),
                ChannelObject("servoid", "u", np.arange(12.0), properties=props),
                ChannelObject("servoid", "y", np.ones(12), properties=props),
                GroupObject("other", {"card": 2}),
                ChannelObject("other", "y", np.zeros(12), properties=props),
                ChannelObject("other", "note", np.array(["a", "b"]), properties={}),
            ])
        out.append(path.read_bytes())
    return out


def _mat_arrays(n: int = 30) -> dict[str, object]:
    import scipy.sparse

    t = 1e-3 * np.arange(n)
    return {
        "t": t[:, None],
        "qm": np.sin(t)[:, None],
        "qg": np.cos(t)[None, :],
        "vir": (0.1 * t)[:, None],
        "i8": np.arange(n, dtype=np.int8),
        "kp": 160.18,
        "label": "rig 7",
        "K": np.arange(6.0).reshape(2, 3),
        "z": np.array([1 + 2j, 3 - 1j]),
        "cells": np.array([[1.0, "a"]], dtype=object),
        "st": {"a": 1.0, "b": np.arange(3.0)},
        "run": {"sig": {"u": np.cos(t)[:, None], "y": np.sin(t)[None, :]}, "fs": 1e3},
        "sp": scipy.sparse.eye(3, format="csc"),
        "flag": np.arange(n) % 2 == 0,
        "empty": np.zeros((0, 0)),
    }


def _mat_seeds(kind: str) -> list[bytes]:
    import scipy.io

    arrays = _mat_arrays()
    out = []
    if kind == "mat4":
        simple = {k: v for k, v in arrays.items() if k in ("t", "qm", "qg", "vir", "kp", "K")}
        for subset in (simple, {"t": arrays["t"], "qm": arrays["qm"], "label": "ab"}):
            buf = io.BytesIO()
            scipy.io.savemat(buf, subset, format="4")
            out.append(buf.getvalue())
        return out
    compress = kind == "mat5z"
    for subset in (arrays, {k: arrays[k] for k in ("t", "qm", "vir", "kp", "label")}):
        buf = io.BytesIO()
        scipy.io.savemat(buf, subset, do_compression=compress)
        out.append(buf.getvalue())
    return out


def _mat73_seeds() -> list[bytes]:
    import h5py

    arrays = _mat_arrays()
    out = []
    with _scratch() as folder:
        path = folder / "a.mat"
        with h5py.File(path, "w", userblock_size=512) as f:
            for name in ("t", "qm", "qg", "vir", "kp", "K"):
                arr = np.atleast_2d(np.asarray(arrays[name], dtype=float))
                ds = f.create_dataset(name, data=arr.T)
                ds.attrs["MATLAB_class"] = np.bytes_("double")
            text = f.create_dataset("label", data=np.frombuffer(b"rig 7", np.uint8)
                                    .astype(np.uint16)[:, None])
            text.attrs["MATLAB_class"] = np.bytes_("char")
            f.create_group("st").create_dataset("a", data=np.ones((1, 1)))
            run = f.create_group("run")
            run.attrs["MATLAB_class"] = np.bytes_("struct")
            sig = run.create_group("sig")
            sig.attrs["MATLAB_class"] = np.bytes_("struct")
            sig["u"], sig["y"] = arrays["qm"].T, arrays["vir"].T
        with path.open("r+b") as fh:
            fh.write(b"MATLAB 7.3 MAT-file, Platform: GLNXA64".ljust(128, b" "))
        out.append(path.read_bytes())
    return out


# MATLAB-written files of scipy's test corpus, as more seeds: big-endian v4 and v5
# (Solaris), MATLAB 7 compressed char, logical and 3-D arrays (scipy ships them).
_CORPUS = {
    "mat4": ("testdouble_4.2c_SOL2.mat", "teststringarray_4.2c_SOL2.mat", "testvec_4_GLNX86.mat"),
    "mat5": ("testdouble_6.1_SOL2.mat", "teststring_6.1_SOL2.mat", "testmatrix_6.1_SOL2.mat",
             "testcellnest_6.1_SOL2.mat"),
    "mat5z": ("testunicode_7.4_GLNX86.mat", "testbool_8_WIN64.mat",
              "test3dmatrix_7.4_GLNX86.mat", "testmulti_7.4_GLNX86.mat"),
}


@cache
def own_seeds(fmt: str) -> tuple[bytes, ...]:
    """The valid seed files servoid builds for a format, once per process."""
    if fmt == "csv":
        return tuple(_csv_seeds())
    if fmt == "toml":
        return tuple(s.encode() for s in _TOML_SEEDS)
    if fmt == "tdms":
        return tuple(_tdms_seeds())
    if fmt == "mat73":
        return tuple(_mat73_seeds())
    return tuple(_mat_seeds(fmt))


@cache
def seeds(fmt: str) -> tuple[bytes, ...]:
    """All seed files of a format: servoid's own, then scipy's MATLAB files."""
    import scipy.io.matlab

    folder = Path(scipy.io.matlab.__file__).parent / "tests" / "data"
    corpus = [folder / name for name in _CORPUS.get(fmt, ())]
    return own_seeds(fmt) + tuple(p.read_bytes() for p in corpus if p.is_file())


def random_ops(rng: random.Random) -> list[Op]:
    """One to three mutations drawn from ``rng``."""
    return [(rng.randrange(N_OPS), rng.getrandbits(32), rng.getrandbits(64))
            for _ in range(rng.choice((1, 1, 2, 3)))]


def mutate(fmt: str, seed: bytes, ops: Sequence[Op]) -> bytes:
    """Apply ``ops`` to ``seed`` (inside one element for mat5z)."""
    if fmt == "mat5z" and ops and ops[0][0] % 4 != 3:
        return _mutate_inflated(seed, ops)
    text = fmt in ("csv", "toml")
    data = bytearray(seed)
    for op in ops:
        data = _apply(data, op, text)
    return bytes(data)


def _apply(data: bytearray, op: Op, text: bool) -> bytearray:
    code, a, b = op
    n = len(data)
    if n == 0:
        return bytearray(b.to_bytes(8, "little")[: a % 9])
    pos = a % n
    if code == 0:
        data[pos] ^= 1 << (b % 8)
    elif code == 1:
        data[pos] = _BYTES[b % len(_BYTES)] if b & 1 else (b >> 8) & 0xFF
    elif code in (2, 3):
        width = 4 if code == 2 else 8
        pos -= pos % 4 if b & 2 else 0
        values = _U32 if code == 2 else _U64
        value = values[(b >> 2) % len(values)]
        if width == 4 and b & 4:
            value = (-value) & 0xFFFFFFFF  # negative int32
        packed = struct.pack("<I" if width == 4 else "<Q", value & (2 ** (8 * width) - 1))
        if b & 1:
            packed = packed[::-1]
        data[pos : pos + width] = packed
    elif code == 4:
        del data[pos:]
    elif code == 5:
        del data[pos : pos + 1 + b % 64]
    elif code == 6:
        chunk = data[pos : pos + 1 + b % 128]
        at = (b >> 8) % n
        data[at:at] = chunk
    elif code == 7:
        data[pos:pos] = (b >> 3).to_bytes(8, "little")[: 1 + b % 8]
    elif code == 8 and text:
        numbers = list(_NUMBER.finditer(bytes(data)))
        if numbers:
            m = numbers[b % len(numbers)]
            new = _TEXT_NUMBERS[(b >> 16) % len(_TEXT_NUMBERS)].encode()
            data[m.start() : m.end()] = new
    elif code == 9 and text:
        data[pos:pos] = _TEXT_BITS[b % len(_TEXT_BITS)].encode()
    elif code == 10 and text:  # a line repeated or dropped
        lines = bytes(data).split(b"\n")
        k = pos % len(lines)
        if b & 1:
            lines.insert(k, lines[k])
        else:
            del lines[k]
        data = bytearray(b"\n".join(lines))
    else:  # binary: swap two 8-byte blocks
        other = b % n
        block_a, block_b = bytes(data[pos : pos + 8]), bytes(data[other : other + 8])
        if len(block_a) == len(block_b):
            data[pos : pos + 8], data[other : other + 8] = block_b, block_a
    return data


def _mutate_inflated(seed: bytes, ops: Sequence[Op]) -> bytes:
    """Mutate the inflated contents of one compressed element, then deflate it again."""
    elements = []
    pos = 128
    while pos + 8 <= len(seed):
        mdtype, count = struct.unpack_from("<2I", seed, pos)
        elements.append((mdtype, seed[pos + 8 : pos + 8 + count]))
        pos += 8 + count
    k = ops[0][1] % len(elements)
    mdtype, body = elements[k]
    inflated = bytearray(zlib.decompress(body))
    for op in ops:
        inflated = _apply(inflated, op, text=False)
    elements[k] = (mdtype, zlib.compress(bytes(inflated)))
    return seed[:128] + b"".join(struct.pack("<2I", m, len(b)) + b for m, b in elements)


def read_input(fmt: str, data: bytes, mode: int, folder: Path) -> str:
    """Write ``data`` in ``folder`` and read it with servoid.

    Returns ``"ok"`` or ``"error:<class>"`` for a :class:`ServoidError`;
    any other exception propagates.
    """
    path = folder / f"input{SUFFIX[fmt]}"
    path.write_bytes(data)
    try:
        _READERS[fmt](path, mode % N_MODES, folder)
    except ServoidError as exc:
        return f"error:{type(exc).__name__}"
    return "ok"


def _read_csv(path: Path, mode: int, folder: Path) -> None:
    from servoid.data import read_csv

    if mode == 0:
        read_csv(path)
    elif mode == 1:
        read_csv(path, time=None, dt=1e-3, roles={"u": ["u"]})
    else:
        read_csv(path, skip_rows=2, skip_columns=["status"], roles={"u": ["u"]})


def _read_toml(path: Path, mode: int, folder: Path) -> None:
    from servoid.data import load_experiment_spec

    record = folder / _CSV_DATA
    if not record.exists():
        record.write_bytes(seeds("csv")[0])
    load_experiment_spec(path)


def _read_tdms(path: Path, mode: int, folder: Path) -> None:
    from servoid.data import read_tdms

    if mode == 0:
        read_tdms(path)
    elif mode == 1:
        read_tdms(path, group="servoid", dt=1e-3, roles={"u": ["u"]})
    else:
        read_tdms(path, channels=["u", "servoid/y"], roles={"u": ["u"]})


def _read_mat(path: Path, mode: int, folder: Path) -> None:
    from servoid.data import read_mat

    if mode == 0:
        read_mat(path, dt=1e-3)
    elif mode == 1:
        read_mat(path, variables=["qm", "vir"], time="t", roles={"y": ["qm"]})
    else:
        read_mat(path, variables=["run.sig.u", "run.sig.y"], dt=1e-3,
                 roles={"y": ["run.sig.y"]})


_READERS: dict[str, Callable[[Path, int, Path], None]] = {
    "csv": _read_csv, "toml": _read_toml, "tdms": _read_tdms,
    "mat4": _read_mat, "mat5": _read_mat, "mat5z": _read_mat, "mat73": _read_mat,
}


@contextmanager
def _scratch() -> Iterator[Path]:
    """A temporary folder as a Path, removed on exit."""
    with tempfile.TemporaryDirectory(prefix="servoid-fuzz-seed-") as name:
        yield Path(name)
