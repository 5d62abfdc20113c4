"""Damaged and hostile rig files: a FileFormatError naming the file, never a crash.

The files of ``tests/data/corrupt/`` are the crash signatures found by the
audit and the fuzzers (see its README); the other tests pin the checks that
stop them: the MAT structural check, the memory budget of compressed and
HDF5 variables, TDMS waveform properties and the truncated CSV line.
"""

from __future__ import annotations

import hashlib
import tracemalloc
from pathlib import Path
from typing import Any

import h5py
import numpy as np
import pytest
import scipy.io
import scipy.io.matlab
from nptdms import ChannelObject, TdmsWriter

from servoid import FileFormatError, OptionError, ServoidError
from servoid.data import read_csv, read_experiment, read_mat, read_tdms

CORRUPT = Path(__file__).parent / "corrupt"
SCIPY_MAT_FILES = sorted((Path(scipy.io.matlab.__file__).parent / "tests" / "data").glob("*.mat"))

# file, reader keywords, expected: a message pattern, or the channel names read.
SIGNATURES: list[tuple[str, dict[str, Any], str | tuple[str, ...]]] = [
    ("mat5_data_type_code.mat", {"dt": 0.1}, r"variable 'x' .*type code 11, not a number type"),
    ("mat5_data_type_code.mat", {"variables": ["x"], "dt": 0.1}, r"variable 'x' .*type code 11"),
    ("mat5_data_type_code.mat", {"variables": ["y"], "dt": 0.1}, ("y",)),
    ("mat5_complex_flag.mat", {"dt": 0.1}, ("y",)),  # a complex array is never loaded
    ("mat5_complex_flag.mat", {"variables": ["x"], "dt": 0.1},
     r"variable 'x' is a complex array of shape \(1, 2\), not a real vector"),
    ("mat5_unused_cell.mat", {"dt": 0.1}, ("x",)),
    ("mat5_unused_cell.mat", {"variables": ["x"], "dt": 0.1}, ("x",)),
    ("mat5_unused_sparse.mat", {"dt": 0.1}, ("x",)),  # a sparse matrix is never loaded
    ("mat5_char_type_code.mat", {"dt": 0.1},
     r"variable 'c' .*char data of type code 11, not a text encoding"),
    ("mat5_char_no_dims.mat", {"dt": 0.1}, r"variable 'c' .*0 dimension\(s\)"),
    ("mat4_huge_header.mat", {"dt": 0.1},
     r"variable 'x' declares 100000×100000 values \(74.5 GiB\) but only 8 bytes follow"),
    ("tdms_wf_increment_text.tdms", {},
     (r"channel 'u' has wf_increment = '0.001 s' \(str\), expected a finite number, the sample "
     r"period \[s\]: fix the property in the file, or pass time=")),
    ("tdms_wf_start_offset_text.tdms", {},
     r"channel 'u' has wf_start_offset = 'later' \(str\), expected a finite number"),
    ("tdms_string_length_4gib.tdms", {}, r"cannot be read as TDMS"),
    ("tdms_interleaved_huge_count.tdms", {}, r"truncated or damaged TDMS file"),
    ("csv_truncated_last_number.csv", {},
     (r"line 8: the last line has no line end and its last value '0.78' \('y'\) is written "
     r"shorter .*end the file with a newline")),
    # issue 21: checked before read, bounded while read, no silent wrong result
    ("mat5_compressed_note_40mib.mat", {"variables": ["x"], "dt": 0.1}, ("x",)),  # k left out
    ("mat5_compressed_note_40mib.mat", {"dt": 0.1},
     r"variable 'k' .*declares 40 MiB inflated, but its header and data take 64 bytes"),
    ("mat5_int64_ns_time.mat", {"time": "t"},
     (r"time vector 't' has no unit and holds integers \(int64\) stepping by 1e\+07: clock "
     r"ticks .*time_unit='ns'")),
    ("mat73_fill_value.mat", {"dt": 0.1},
     r"variable 'big' declares shape \(1, 268435456\) \(2 GiB\) but stores only 0 bytes"),
    ("mat73_fill_value.mat", {"variables": ["x"], "dt": 0.1}, ("x",)),
    ("mat73_external_link.mat", {"variables": ["far"], "dt": 0.1},
     (r"variable 'far' is an external link to '\.\./\.\./outside/secret\.mat'.*"
     r"allow_external=True")),
    ("mat73_external_link.mat", {"dt": 0.1}, ("x",)),  # not asked for: never opened
    ("tdms_wf_start_offset_1e308.tdms", {},
     r"wf_start_offset = 1e\+308 s is too large for wf_increment = 0\.001 s"),
    ("tdms_wf_increment_5e-324.tdms", {}, r"wf_increment = 4\.94066e-324 s is outside"),
    ("csv_utf16.csv", {},
     (r"not a text CSV file in UTF-8: it is UTF-16 \(little-endian\) text, with a byte-order "
     r"mark \(FF FE\)\. .*iconv")),
    ("csv_digit_grouping.csv", {},
     r"line 5, column 2: '1_000' groups its digits with '_'.*write the number without"),
    ("csv_bom_inside.csv", {}, r"line 10, column 1: .* holds a byte-order mark \(U\+FEFF\)"),
    ("csv_integer_ms_time.csv", {},
     (r"time column 'time' has no unit and holds whole numbers stepping by 1: likely "
     r"milliseconds .*time_unit='ms'")),
]


def _digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.mark.filterwarnings("ignore")
@pytest.mark.parametrize(("name", "kwargs", "expected"), SIGNATURES)
def test_crash_signature(name: str, kwargs: dict[str, Any], expected: Any) -> None:
    path = CORRUPT / name
    digest = _digest(path)
    tracemalloc.start()
    try:
        if isinstance(expected, tuple):
            assert read_experiment(path, **kwargs).names == expected
        else:
            with pytest.raises(FileFormatError, match=expected) as info:
                read_experiment(path, **kwargs)
            assert name in str(info.value)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    # Files of a few hundred bytes whose damaged sizes declare GiB to TiB: what the
    # reader allocates must follow the file, not the declarations.
    assert peak < 32 * 2**20
    assert _digest(path) == digest  # reading never modifies the file


def test_every_signature_file_is_tested() -> None:
    tested = {name for name, _, _ in SIGNATURES}
    assert tested == {p.name for p in CORRUPT.iterdir() if p.name != "README.md"}


# -- the MAT check against real MATLAB files -------------------------------------------------


@pytest.mark.filterwarnings("ignore")
@pytest.mark.parametrize("path", SCIPY_MAT_FILES, ids=lambda p: p.name)
def test_mat_check_accepts_real_files(path: Path) -> None:
    """scipy's corpus (MATLAB 4.2c to 7.4, big- and little-endian, v4 to v7.3).

    Whatever scipy reads, the check must pass and load every numeric and char
    variable; whatever it rejects must be a ServoidError too.
    """
    try:
        reference = scipy.io.loadmat(path, chars_as_strings=True)
    except NotImplementedError:  # v7.3: h5py's turn
        reference = None
    except Exception:  # noqa: BLE001 - scipy's verdict: a damaged file
        with pytest.raises(ServoidError):
            read_mat(path, dt=0.1)
        return
    try:
        read_mat(path, dt=0.1)
    except ServoidError as exc:  # no vectors, different lengths: fine; not a damage verdict
        assert "damaged" not in str(exc) and "truncated" not in str(exc), exc
    if reference is None:
        return
    from servoid.data._mat_check import check_mat

    version = scipy.io.matlab.matfile_version(path)[0]
    entries = check_mat(path, version, None, 2**31)
    for name, value in reference.items():
        arr = np.asarray(value)
        if name.startswith("__") or arr.dtype.kind not in "biufU":
            continue
        assert entries[name].loadable, name


# -- memory budget ---------------------------------------------------------------------------


def test_compressed_variable_over_budget(tmp_path: Path) -> None:
    path = tmp_path / "zeros.mat"
    scipy.io.savemat(path, {"x": np.zeros((1, 10**6))}, do_compression=True)
    assert path.stat().st_size < 20_000  # 8 MB of zeros deflate to a few KB
    with pytest.raises(FileFormatError, match=r"'x' .*over the 977 KiB budget .*max_bytes="):
        read_mat(path, dt=0.1, max_bytes=10**6)
    assert read_mat(path, dt=0.1).n_samples == 10**6


def test_hdf5_variable_over_budget(tmp_path: Path) -> None:
    path = tmp_path / "big73.mat"
    with h5py.File(path, "w") as f:  # declared, never written: the file stays small
        ds = f.create_dataset("x", shape=(10**9, 1), dtype="f8", chunks=(1024, 1))
        ds.attrs["MATLAB_class"] = np.bytes_("double")
        f.create_dataset("y", data=np.ones((5, 1))).attrs["MATLAB_class"] = np.bytes_("double")
    with pytest.raises(FileFormatError, match=r"'x' declares shape \(1, 1000000000\) .* budget"):
        read_mat(path, dt=0.1)
    assert read_mat(path, variables=["y"], dt=0.1).names == ("y",)  # x never read


@pytest.mark.parametrize("bad", [0, -1, 1.5, True, "1GB"])
def test_max_bytes_must_be_positive_int(tmp_path: Path, bad: object) -> None:
    path = tmp_path / "a.mat"
    scipy.io.savemat(path, {"a": np.ones(3)})
    with pytest.raises(OptionError, match="max_bytes must be a positive whole number"):
        read_mat(path, dt=0.1, max_bytes=bad)  # type: ignore[arg-type]


def test_named_variables_keep_notes_and_drop_damaged_ones(tmp_path: Path) -> None:
    path = tmp_path / "rig.mat"
    scipy.io.savemat(path, {"qm": np.arange(4.0), "kp": 2.5, "kv": 7.0, "label": "rig 7"})
    data = bytearray(path.read_bytes())
    # kp's data tag is the first miDOUBLE tag of 8 bytes; make its type code unknown
    at = data.find(np.array([9, 8], "<u4").tobytes())
    data[at] = 11
    path.write_bytes(bytes(data))
    exp = read_mat(path, variables=["qm"], dt=0.1)
    assert exp.notes == {"kv": 7.0, "label": "rig 7"}  # kp is damaged and nobody asked for it
    with pytest.raises(FileFormatError, match=r"variable 'kp' .*type code 11"):
        read_mat(path, dt=0.1)  # every variable asked for: kp's damage is an error


# -- TDMS waveform properties and the index file ---------------------------------------------


def _tdms(path: Path, **props: Any) -> Path:
    with TdmsWriter(str(path)) as writer:
        writer.write_segment([ChannelObject("g", "u", np.arange(4.0), properties=props)])
    return path


@pytest.mark.parametrize(
    ("props", "message"),
    [
        ({"wf_increment": float("nan")}, r"wf_increment = nan .*expected a finite number"),
        ({"wf_increment": True}, r"wf_increment = True \(bool\)"),
        ({"wf_increment": 0.0}, r"wf_increment \(the sample period\) is 0.0 s, not > 0"),
        ({"wf_increment": -1e-3}, r"is -0.001 s, not > 0: fix the property"),
        ({"wf_increment": 1e-3, "wf_start_offset": float("inf")}, r"wf_start_offset = inf"),
    ],
)
def test_tdms_bad_waveform_timing(tmp_path: Path, props: dict[str, Any], message: str) -> None:
    with pytest.raises(FileFormatError, match=message):
        read_tdms(_tdms(tmp_path / "t.tdms", **props))


def test_tdms_bad_timing_is_not_needed_with_a_time_channel(tmp_path: Path) -> None:
    path = tmp_path / "t.tdms"
    with TdmsWriter(str(path)) as writer:
        writer.write_segment([
            ChannelObject("g", "t", 1e-3 * np.arange(4.0)),
            ChannelObject("g", "u", np.arange(4.0), properties={"wf_increment": "n/a"}),
        ])
    assert read_tdms(path, time="t").dt == pytest.approx(1e-3, rel=1e-12)  # ε·4 of the stamps


def test_tdms_index_file_is_ignored(tmp_path: Path) -> None:
    path = _tdms(tmp_path / "t.tdms", wf_increment=1e-3)
    (tmp_path / "t.tdms_index").write_bytes(b"TDSh" + b"\xff" * 60)  # stale or damaged
    assert read_tdms(path).n_samples == 4


# -- CSV truncated in its last number --------------------------------------------------------

_FIXED = "t [s],y [V]\n" + "".join(f"{k / 1000:.3f},{0.1 + k / 7:.6f}\n" for k in range(8))
_REPR = "t [s],y [V]\n" + "".join(f"{k / 1000!r},{float(np.sin(k + 1))!r}\n" for k in range(8))


@pytest.mark.parametrize(
    ("text", "message"),
    [
        (_FIXED + "0.008,1.23",
         r"line 10: .*'1.23' \('y'\) .*\(2 decimals, every value above has 6\)"),
        (_FIXED + "0.008,1.", r"'1.' .*0 decimals"),
        (_FIXED + "0.008,1", r"'1' .*0 decimals"),
        ("t [s],y\n" + "".join(f"{k},{k + 1}.5e-05\n" for k in range(8)) + "8,2.5e-0",
         r"'2.5e-0' .*every value above has 2 exponent digits"),
        (_REPR + "0.008,0.98", r"'0.98' .*4 characters, the shortest above is"),
        (_FIXED + "0.008", (r"line 10: 1 field\(s\), the header has 2 \(the last line, with no "
                           r"line end: the file looks truncated")),
    ],
)
def test_csv_truncated_last_line(tmp_path: Path, text: str, message: str) -> None:
    path = tmp_path / "cut.csv"
    path.write_text(text)
    with pytest.raises(FileFormatError, match=message):
        read_csv(path, time="t")


@pytest.mark.parametrize(
    ("text", "n"),
    [
        (_FIXED + "0.008,1.234567", 9),  # complete, no line end
        (_FIXED + "0.008,1.23\n", 9),  # a line end: written that way on purpose
        (_FIXED + "0.008,1.23\r\n", 9),
        (_FIXED + "# end of run", 8),  # the last line is a comment
        (_REPR + "0.008,0.9893582466233818", 9),  # free format, as long as the others
        ("t [s],y\n0,1.5\n0.001,2.5\n0.002,3", 3),  # too few lines above to know a format
        ("t [s],y\n" + "".join(f"{k / 1000},{k}\n" for k in range(8)) + "0.008,8", 9),  # integers
    ],
)
def test_csv_complete_last_line(tmp_path: Path, text: str, n: int) -> None:
    path = tmp_path / "ok.csv"
    path.write_text(text)
    assert read_csv(path, time="t").n_samples == n
