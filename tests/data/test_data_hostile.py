"""Inputs checked before they are read and bounded while read (issue 21, items 4-6).

What a path can name besides a regular file (a FIFO, a device, a socket, a
link loop), files larger than the budget or still growing, HDF5 files that
point elsewhere or never stop, time stamps in integer ticks, and the
records an experiment file lists twice: each a :class:`ServoidError` naming
the problem and the fix, never a hang, a blow-up or a silent wrong result.
"""

from __future__ import annotations

import os
import signal
import socket
import struct
import tracemalloc
import zlib
from collections.abc import Iterator
from pathlib import Path

import h5py
import numpy as np
import pytest
import scipy.io
from nptdms import ChannelObject, GroupObject, RootObject, TdmsWriter

from servoid import DataError, Experiment, FileFormatError, MissingFileError
from servoid._files import open_input, read_input_text
from servoid.data import (
    _child,
    _mat73,
    load_experiment_spec,
    read_csv,
    read_experiment,
    read_mat,
    read_tdms,
    write_csv,
)
from servoid.data._csv import header_names

N = 300


class Blocked(Exception):
    """A read blocked (not an OSError, which a reader may catch)."""


@pytest.fixture
def deadline() -> Iterator[None]:
    """Fail, rather than hang, a test whose read blocks (a FIFO's open is interruptible)."""
    def expired(signum: int, frame: object) -> None:
        raise Blocked("the read blocked: it should have been refused before opening")

    old = signal.signal(signal.SIGALRM, expired)
    signal.alarm(20)
    yield
    signal.alarm(0)
    signal.signal(signal.SIGALRM, old)


def _record(n: int = N) -> Experiment:
    rng = np.random.default_rng(5)
    return Experiment.from_arrays(1e-3, u=rng.standard_normal(n), y=rng.standard_normal(n),
                                  name="rec")


def _toml(folder: Path, data: str, validation: str = "") -> Path:
    text = f'[data]\nfile = {data}\n\n[channels.u]\nrole = "u"\n\n[channels.y]\nrole = "y"\n'
    if validation:
        text += f"\n[validation]\nfile = {validation}\n"
    path = folder / "exp.toml"
    path.write_text(text, encoding="utf-8")
    return path


# -- what a path names ---------------------------------------------------------------------------


@pytest.mark.parametrize("suffix", [".csv", ".tdms", ".mat"])
def test_a_fifo_is_refused_by_name_without_blocking(tmp_path, deadline, suffix):
    fifo = tmp_path / f"data{suffix}"
    os.mkfifo(fifo)
    with pytest.raises(FileFormatError, match=r"is a named pipe \(FIFO\), not a regular file"):
        read_experiment(fifo, dt=1e-3)


def test_a_fifo_in_an_experiment_file_is_refused_without_blocking(tmp_path, deadline):
    """The experiment file read the CSV header first (to choose columns): that blocked."""
    os.mkfifo(tmp_path / "data.csv")
    spec = load_experiment_spec(_toml(tmp_path, '"data.csv"'))
    assert header_names(tmp_path / "data.csv") is None
    with pytest.raises(FileFormatError, match=r"data\.csv is a named pipe \(FIFO\)"):
        spec.load()
    os.mkfifo(tmp_path / "fifo.toml")
    with pytest.raises(FileFormatError, match=r"fifo\.toml is a named pipe \(FIFO\)"):
        load_experiment_spec(tmp_path / "fifo.toml")


def test_a_link_to_a_device_is_refused_unread(tmp_path, deadline):
    link = tmp_path / "data.csv"
    link.symlink_to("/dev/zero")
    tracemalloc.start()
    try:
        with pytest.raises(FileFormatError, match=r"a symbolic link to /dev/zero\) is a character "
                           r"device, not a regular file"):
            load_experiment_spec(_toml(tmp_path, '"data.csv"')).load()
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 8 * 2**20  # nothing read from the device (it grew to 3.9 GB before)


def test_a_socket_is_refused_by_name(tmp_path):
    path = tmp_path / "s.csv"
    server = socket.socket(socket.AF_UNIX)
    try:
        server.bind(str(path))
        with pytest.raises(FileFormatError, match=r"is a socket, not a regular file"):
            read_csv(path)
    finally:
        server.close()


def test_link_loops_dangling_links_and_nul_bytes(tmp_path):
    loop = tmp_path / "loop.csv"
    loop.symlink_to(loop.name)
    with pytest.raises(FileFormatError, match=r"loop\.csv is a symbolic link that loops"):
        read_csv(loop)
    dangling = tmp_path / "gone.csv"
    dangling.symlink_to("nowhere.csv")
    with pytest.raises(MissingFileError, match=r"a symbolic link to nowhere\.csv\): no such "
                       "file at the link's end"):
        read_csv(dangling)
    with pytest.raises(DataError, match=r"holds a NUL byte"):
        read_csv(str(tmp_path / "a\0b.csv"))


def test_a_folder_is_named_a_folder(tmp_path):
    (tmp_path / "sub.csv").mkdir()
    with pytest.raises(FileFormatError, match=r"sub\.csv is a folder, not a regular file"):
        read_csv(tmp_path / "sub.csv")


def test_the_budget_is_applied_before_opening(tmp_path, monkeypatch):
    path = write_csv(_record(), tmp_path / "a.csv")
    import servoid._files as files

    def no_open(*args: object, **kwargs: object) -> int:
        raise AssertionError("opened a file over the budget")

    monkeypatch.setattr(files.os, "open", no_open)
    with pytest.raises(DataError, match=r"over the budget of 100 bytes; .*pass max_bytes="):
        read_csv(path, max_bytes=100)


def test_a_growing_file_is_read_as_it_was_when_checked(tmp_path):
    path = tmp_path / "log.txt"
    path.write_bytes(b"x" * 1000)
    with open_input(path, max_bytes=5000) as f:
        with path.open("ab") as other:
            other.write(b"y" * 10_000)  # a logger still writing
        assert f.read() == b"x" * 1000
        f.seek(0)
        assert f.readline() == b"x" * 1000  # and line by line
        f.seek(0)
        assert len(f.read(4096)) == 1000


def test_text_inputs_name_their_encoding(tmp_path):
    path = tmp_path / "e.toml"
    path.write_bytes("[data]\nfile = 'a.csv'\n".encode("utf-16"))
    with pytest.raises(FileFormatError, match=r"UTF-16 \(little-endian\) text, with a byte-order "
                       r"mark \(FF FE\); servoid reads UTF-8 text: save it as UTF-8"):
        read_input_text(path, "experiment file")
    path.write_bytes("\ufeff[data]\n".encode())  # a UTF-8 mark (Notepad): dropped
    assert read_input_text(path, "experiment file") == "[data]\n"
    with pytest.raises(DataError, match=r"over the budget of 4 bytes"):
        read_input_text(path, "experiment file", max_bytes=4)


# -- CSV messages ----------------------------------------------------------------------------------


def _csv_text(rows: int = 20) -> str:
    return "time [s],u [V],y [m]\n" + "".join(
        f"{k * 1e-3!r},{np.sin(k):.6f},{np.cos(k):.6f}\n" for k in range(rows))


@pytest.mark.parametrize(("encoding", "words"), [
    ("utf-16", r"UTF-16 \(little-endian\) text, with a byte-order mark \(FF FE\)"),
    ("utf-16-be", r"UTF-16 \(big-endian\) text, without a byte-order mark"),
    ("utf-32", r"UTF-32 \(little-endian\) text, with a byte-order mark \(FF FE 00 00\)"),
])
def test_a_utf16_csv_names_its_encoding_and_the_fix(tmp_path, encoding, words):
    path = tmp_path / "a.csv"
    path.write_bytes(_csv_text().encode(encoding))
    with pytest.raises(FileFormatError, match=words + r"\. servoid reads CSV files in UTF-8: "
                       r"save it as 'CSV UTF-8'"):
        read_csv(path)


def test_digit_grouping_is_named_with_its_line(tmp_path):
    path = tmp_path / "a.csv"
    lines = _csv_text().splitlines()
    lines[7] = "0.006,1_000,0.5"
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    with pytest.raises(FileFormatError, match=r"a\.csv, line 8, column 2: '1_000' groups its "
                       r"digits with '_'"):
        read_csv(path)


def test_a_byte_order_mark_inside_the_file_is_named(tmp_path):
    path = tmp_path / "a.csv"
    text = _csv_text()
    path.write_text(text + "\ufeff" + text.splitlines()[3] + "\n", encoding="utf-8")
    with pytest.raises(FileFormatError, match=r"line 22, column 1: .* holds a byte-order mark "
                       r"\(U\+FEFF\)"):
        read_csv(path)
    path.write_text("# exported\n\ufefftime [s],u [V],y [m]\n0,1,2\n", encoding="utf-8")
    with pytest.raises(FileFormatError, match=r"line 2: the header row holds a byte-order mark"):
        read_csv(path, dt=1e-3, time=None)
    path.write_text("\ufeff" + text, encoding="utf-8")  # at the start: the usual, dropped
    assert read_csv(path).names == ("u", "y")


def test_a_huge_header_cell_and_a_bad_delimiter_are_errors(tmp_path):
    path = tmp_path / "a.csv"
    path.write_text("x" * 140_000 + "," + _csv_text(), encoding="utf-8")
    with pytest.raises(FileFormatError, match=r"line 1: the header row cannot be split into "
                       r"cells .*140,000 characters"):
        read_csv(path)
    good = tmp_path / "b.csv"
    good.write_text(_csv_text(), encoding="utf-8")
    for bad in ("narx", '"', ".", "1", "\n"):
        with pytest.raises(DataError, match="delimiter"):
            read_csv(good, delimiter=bad)
        assert header_names(good, delimiter=bad) is None


def test_a_line_without_end_is_not_read_whole(tmp_path, monkeypatch):
    from servoid.data import _csv

    monkeypatch.setattr(_csv, "_LINE_LIMIT", 1000)
    path = tmp_path / "a.csv"
    path.write_bytes(b"0" * 5000)
    with pytest.raises(FileFormatError, match=r"line 1: more than 1,000 characters without a "
                       "line end"):
        read_csv(path)


# -- time stamps in ticks ------------------------------------------------------------------------


def test_integer_nanoseconds_in_a_mat_file_are_not_seconds(tmp_path):
    path = tmp_path / "ns.mat"
    ticks = np.arange(N, dtype=np.int64) * 10_000_000  # 100 Hz in int64 nanoseconds
    scipy.io.savemat(path, {"t": ticks[:, None], "u": np.sin(ticks / 1e8)[:, None]})
    with pytest.raises(FileFormatError, match=r"time vector 't' has no unit and holds integers "
                       r"\(int64\) stepping by 1e\+07: clock ticks .*time_unit='ns'"):
        read_mat(path, time="t")  # read as seconds before: dt = 1e7 s
    assert read_mat(path, time="t", time_unit="ns").dt == pytest.approx(0.01, rel=1e-12)


def test_integer_ticks_in_v73_and_tdms_files(tmp_path):
    ticks = np.arange(N, dtype=np.int64) * 1000  # 1 kHz in microseconds
    path = tmp_path / "us.mat"
    with h5py.File(path, "w") as f:
        for name, value in (("t", ticks), ("u", np.sin(ticks / 1e4))):
            f.create_dataset(name, data=value[None, :])
            f[name].attrs["MATLAB_class"] = np.bytes_("int64" if name == "t" else "double")
    with pytest.raises(FileFormatError, match=r"time vector 't' has no unit and holds integers"):
        read_mat(path, time="t")
    assert read_mat(path, time="t", time_unit="us").dt == pytest.approx(1e-3, rel=1e-12)
    tdms = tmp_path / "ticks.tdms"
    with TdmsWriter(str(tdms)) as writer:
        writer.write_segment([RootObject({}), GroupObject("g", {}),
                              ChannelObject("g", "t", ticks), ChannelObject("g", "u", 1.0 * ticks)])
    with pytest.raises(FileFormatError, match=r"time channel 't' has no unit and holds integers"):
        read_tdms(tdms, time="t")
    assert read_tdms(tdms, time="t", time_unit="us").dt == pytest.approx(1e-3, rel=1e-12)


def test_milliseconds_as_whole_numbers_stop_every_reader(tmp_path):
    ms = np.arange(N, dtype=float)
    path = tmp_path / "ms.mat"
    scipy.io.savemat(path, {"t": ms[:, None], "u": np.sin(ms)[:, None]})
    with pytest.raises(FileFormatError, match=r"holds whole numbers stepping by 1: likely "
                       "milliseconds"):
        read_mat(path, time="t")
    assert read_mat(path, time="t", time_unit="ms").dt == pytest.approx(1e-3)
    assert read_mat(path, time="t", time_unit="s").dt == 1.0  # stated: taken as stated


# -- TDMS and Experiment timing ------------------------------------------------------------------


@pytest.mark.parametrize(("props", "words"), [
    ({"wf_increment": 1e-3, "wf_start_offset": 1e308},
     r"wf_start_offset = 1e\+308 s is too large for wf_increment = 0\.001 s"),
    ({"wf_increment": 5e-324, "wf_start_offset": 0.0},
     r"wf_increment = 4\.94066e-324 s is outside the sample periods servoid computes with"),
    ({"wf_increment": 1e300, "wf_start_offset": 0.0}, r"wf_increment = 1e\+300 s is outside"),
])
def test_absurd_waveform_timing_is_a_clear_error(tmp_path, props, words):
    path = tmp_path / "w.tdms"
    with TdmsWriter(str(path)) as writer:
        writer.write_segment([RootObject({}), GroupObject("g", {}),
                              ChannelObject("g", "u", np.sin(np.arange(N)), properties=props)])
    with pytest.raises(FileFormatError, match=words + r".*a damaged waveform property"):
        read_tdms(path)


def test_an_experiment_needs_a_usable_time_base():
    with pytest.raises(DataError, match=r"dt = 4\.94066e-324 s is outside"):
        Experiment.from_arrays(5e-324, u=np.ones(4), y=np.ones(4))
    with pytest.raises(DataError, match=r"t0 = 1e\+20 s is too large for dt = 0\.001 s"):
        Experiment(_record().channels, 1e-3, t0=1e20)
    ok = Experiment(_record().channels, 1e-6, t0=1.7e9)  # an epoch offset at 1 MHz resolves
    assert ok.t0 == 1.7e9


# -- MAT v5: inflation bounded -------------------------------------------------------------------


def _compressed(name: str, value: float, pad: int) -> bytes:
    """A compressed v5 element: a 1×1 double whose matrix element declares ``pad`` more bytes."""
    body = struct.pack("<2I2I", 6, 8, 6, 0) + struct.pack("<2I2i", 5, 8, 1, 1)
    raw = name.encode()
    body += struct.pack("<2I", 1, len(raw)) + raw + b"\0" * (-len(raw) % 8)
    body += struct.pack("<2I", 9, 8) + struct.pack("<d", value)
    inner = struct.pack("<2I", 14, len(body) + pad) + body
    packer = zlib.compressobj(9)
    data = packer.compress(inner) + packer.compress(b"\0" * pad) + packer.flush()
    return struct.pack("<2I", 15, len(data)) + data


def test_a_compressed_note_is_inflated_only_as_far_as_its_data(tmp_path):
    """A 1×1 scalar whose element declares 64 MiB of zeros: read for the notes, it was inflated."""
    path = tmp_path / "pad.mat"
    scipy.io.savemat(path, {"x": np.arange(N, dtype=float)[:, None]})
    path.write_bytes(path.read_bytes() + _compressed("k", 2.5, 64 * 2**20)
                     + _compressed("g", 1.5, 0))
    tracemalloc.start()
    try:
        exp = read_mat(path, variables=["x"], dt=1e-3)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert exp.notes == {"g": 1.5}  # the damaged note is left out, the sound one read
    assert peak < 16 * 2**20  # the declared 64 MiB were never inflated
    with pytest.raises(FileFormatError, match=r"variable 'k' .*declares 64 MiB inflated, but "
                       r"its header and data take 64 bytes"):
        read_mat(path, variables=["k"], dt=1e-3)


# -- MAT v7.3: what HDF5 can point to, and a read that never ends --------------------------------


def _v73(path: Path) -> Path:
    with h5py.File(path, "w") as f:
        for name in ("x", "y"):
            f.create_dataset(name, data=np.sin(np.arange(N) + len(name))[None, :])
            f[name].attrs["MATLAB_class"] = np.bytes_("double")
    return path


def test_v73_external_links_are_refused_unless_allowed(tmp_path):
    (tmp_path / "outside").mkdir()
    other = _v73(tmp_path / "outside" / "secret.mat")
    path = _v73(tmp_path / "a.mat")
    with h5py.File(path, "a") as f:
        f["far"] = h5py.ExternalLink(str(other), "/x")
    with pytest.raises(FileFormatError, match=r"variable 'far' is an external link to .*secret"
                       r"\.mat.*pass allow_external=True"):
        read_mat(path, variables=["far"], dt=1e-3)
    assert read_mat(path, dt=1e-3).names == ("x", "y")  # not asked for: never opened
    exp = read_mat(path, variables=["far"], dt=1e-3, allow_external=True)
    np.testing.assert_array_equal(exp["far"], read_mat(other, dt=1e-3)["x"])
    with h5py.File(path, "a") as f:  # a soft link whose path runs through the external one
        f["group"] = h5py.ExternalLink(str(other), "/")
        f["near"] = h5py.SoftLink("/group/y")
        f["loop"] = h5py.SoftLink("/loop")
    with pytest.raises(FileFormatError, match=r"variable 'near' is an external link"):
        read_mat(path, variables=["near"], dt=1e-3)
    with pytest.raises(FileFormatError, match=r"variable 'loop' goes through more than 16 soft "
                       "links"):
        read_mat(path, variables=["loop"], dt=1e-3)


def test_v73_external_and_virtual_storage_are_refused(tmp_path):
    raw = tmp_path / "raw.bin"
    raw.write_bytes(np.arange(N, dtype="<f8").tobytes())
    path = _v73(tmp_path / "a.mat")
    with h5py.File(path, "a") as f:
        f.create_dataset("ext", shape=(1, N), dtype="<f8", external=[(str(raw), 0, 8 * N)])
        layout = h5py.VirtualLayout(shape=(1, N), dtype="<f8")
        layout[0, :] = h5py.VirtualSource(str(tmp_path / "a.mat"), "x", shape=(1, N))[0, :]
        f.create_virtual_dataset("virt", layout)
    for name, kind in (("ext", "external storage"), ("virt", "virtual dataset")):
        with pytest.raises(FileFormatError, match=rf"variable '{name}' keeps its values in .*"
                           rf"\({kind}\): reading it would open files you did not name"):
            read_mat(path, variables=[name], dt=1e-3)
    assert read_mat(path, variables=["ext"], dt=1e-3, allow_external=True)["ext"][5] == 5.0


def test_v73_fill_value_dataset_is_refused_unread(tmp_path):
    path = _v73(tmp_path / "a.mat")
    with h5py.File(path, "a") as f:
        f.create_dataset("big", shape=(1, 2**27), dtype="<f8")  # 1 GiB declared, none stored
        f["big"].attrs["MATLAB_class"] = np.bytes_("double")
    assert path.stat().st_size < 100_000
    with pytest.raises(FileFormatError, match=r"variable 'big' declares shape \(134217728, 1\) "
                       r"\(1 GiB\) but stores only 0 bytes"):
        read_mat(path, variables=["big"], dt=1e-3)
    assert read_mat(path, variables=["x"], dt=1e-3).names == ("x",)


def test_a_v73_read_that_stops_making_progress_is_stopped(tmp_path, monkeypatch, deadline):
    """libhdf5 spun forever on a damaged file; the read runs in a child that can be abandoned."""
    path = _v73(tmp_path / "a.mat")

    def spin(self: object, wanted: object) -> None:
        while True:  # as a C loop would: no heartbeat, no return
            pass

    monkeypatch.setattr(_mat73._Reader, "read", spin)
    monkeypatch.setattr(_child, "STALL_SECONDS", 0.5)
    with pytest.raises(FileFormatError, match=r"a\.mat: reading it as a MAT v7\.3 \(HDF5\) file "
                       r"made no progress for 0\.5 s, so it was stopped"):
        read_mat(path, dt=1e-3)


def test_a_v73_read_that_crashes_takes_only_the_child(tmp_path, monkeypatch):
    path = _v73(tmp_path / "a.mat")

    def crash(self: object, wanted: object) -> None:
        os.kill(os.getpid(), signal.SIGSEGV)

    monkeypatch.setattr(_mat73._Reader, "read", crash)
    with pytest.raises(FileFormatError, match=r"the file library crashed \(SIGSEGV\)"):
        read_mat(path, dt=1e-3)


def test_v73_errors_and_values_come_back_from_the_child(tmp_path):
    path = _v73(tmp_path / "a.mat")
    exp = read_mat(path, dt=1e-3)
    np.testing.assert_array_equal(exp["y"], np.sin(np.arange(N) + 1))
    with pytest.raises(FileFormatError, match=r"over the 1 KiB budget"):
        read_mat(path, dt=1e-3, max_bytes=1024)


# -- the same record twice -----------------------------------------------------------------------


def test_the_same_record_twice_is_refused(tmp_path):
    write_csv(_record(), tmp_path / "a.csv")
    (tmp_path / "copy.csv").write_bytes((tmp_path / "a.csv").read_bytes())
    write_csv(_record(2 * N), tmp_path / "b.csv")
    spec = load_experiment_spec(_toml(tmp_path, '["a.csv", "copy.csv"]', '"b.csv"'))
    with pytest.raises(FileFormatError, match=r"\[data\] file lists the same record twice: .*a\.csv"
                       r" and .*copy\.csv hold the same samples.*shrink by √2"):
        spec.records()
    spec = load_experiment_spec(_toml(tmp_path, '["a.csv", "./a.csv"]', '"b.csv"'))
    with pytest.raises(FileFormatError, match="the same record twice"):
        spec.records()


def test_a_validation_record_equal_to_the_estimation_record_is_refused(tmp_path):
    write_csv(_record(), tmp_path / "a.csv")
    (tmp_path / "val.csv").write_bytes((tmp_path / "a.csv").read_bytes())
    spec = load_experiment_spec(_toml(tmp_path, '"a.csv"', '"val.csv"'))
    with pytest.raises(FileFormatError, match=r"\[validation\] file .*val\.csv holds the same "
                       r"samples as the estimation record .*a\.csv.*remove \[validation\]"):
        spec.records()
    write_csv(_record(2 * N), tmp_path / "b.csv")
    _, (validation,) = load_experiment_spec(
        _toml(tmp_path, '"a.csv"', '"b.csv"')).records()
    assert validation.n_samples == 2 * N
