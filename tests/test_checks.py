"""servoid._checks: the shared boundary validators."""

from __future__ import annotations

import math

import numpy as np
import pytest

from servoid import DataError, FileFormatError, MissingFileError, OptionTypeError, ServoidError
from servoid._checks import (
    as_array,
    as_bool,
    as_float,
    as_float_list,
    as_instance,
    as_int,
    as_int_list,
    as_mapping,
    as_path,
    as_str,
    as_str_list,
    read_json,
    type_error,
)


def test_option_type_error_is_both_servoid_and_type_error():
    assert issubclass(OptionTypeError, ServoidError)
    assert issubclass(OptionTypeError, TypeError)
    err = type_error("na", "three", "an integer", where="[identify]")
    assert isinstance(err, OptionTypeError)
    assert str(err) == "[identify] na must be an integer, got 'three' (str)"


def test_as_int_accepts_integers():
    assert as_int("n", 3) == 3
    out = as_int("n", np.int64(4), minimum=0, maximum=4)
    assert out == 4 and type(out) is int


@pytest.mark.parametrize(
    ("value", "kwargs", "error", "message"),
    [
        ("three", {"where": "[identify]"}, OptionTypeError,
         "[identify] na must be an integer, got 'three' (str)"),
        (2.0, {}, OptionTypeError, "na must be an integer, got 2.0 (float)"),
        (True, {}, OptionTypeError, "na must be an integer, got True (bool)"),
        (None, {}, OptionTypeError, "na must be an integer, got None (NoneType)"),
        (-1, {"minimum": 0}, DataError, "na must be >= 0, got -1"),
        (9, {"maximum": 8}, DataError, "na must be <= 8, got 9"),
        (9, {"minimum": 1, "maximum": 8, "where": "[x]"}, DataError,
         "[x] na must lie in 1..8, got 9"),
    ],
)
def test_as_int_refuses(value, kwargs, error, message):
    with pytest.raises(error) as info:
        as_int("na", value, **kwargs)
    assert str(info.value) == message


def test_as_float_accepts_numbers():
    assert as_float("x", 2) == 2.0 and type(as_float("x", 2)) is float
    assert as_float("x", np.float32(0.5)) == 0.5
    assert math.isinf(as_float("x", math.inf, finite=False))
    assert as_float("x", 0.0, nonneg=True) == 0.0


@pytest.mark.parametrize(
    ("value", "kwargs", "error", "message"),
    [
        ("x", {"where": "[loop]"}, OptionTypeError, "[loop] c must be a number, got 'x' (str)"),
        (True, {}, OptionTypeError, "c must be a number, got True (bool)"),
        ([1.0], {}, OptionTypeError, "c must be a number, got [1.0] (list)"),
        (math.nan, {}, DataError, "c must be finite, got nan"),
        (math.inf, {}, DataError, "c must be finite, got inf"),
        (0.0, {"positive": True, "unit": "Hz"}, DataError, "c must be > 0 Hz, got 0"),
        (-2.5, {"nonneg": True}, DataError, "c must be >= 0, got -2.5"),
        (math.nan, {"positive": True, "finite": False}, DataError, "c must be > 0, got nan"),
    ],
)
def test_as_float_refuses(value, kwargs, error, message):
    with pytest.raises(error) as info:
        as_float("c", value, **kwargs)
    assert str(info.value) == message


def test_as_bool_str_mapping():
    assert as_bool("refine", False) is False
    with pytest.raises(OptionTypeError, match=r"^\[identify\] refine must be true or false, "
                       r"got 1 \(int\)$"):
        as_bool("refine", 1, where="[identify]")
    assert as_str("output", "y") == "y"
    assert as_str("output", "", empty=True) == ""
    with pytest.raises(OptionTypeError, match=r"output must be a string, got 5 \(int\)"):
        as_str("output", 5)
    with pytest.raises(DataError, match="output must be a non-empty string"):
        as_str("output", "")
    assert as_mapping("F", {"num": [1]}) == {"num": [1]}
    with pytest.raises(OptionTypeError, match=r"F must be a table, got 3 \(int\)"):
        as_mapping("F", 3)


def test_lists():
    assert as_int_list("orders", (2, 2, 1), length=3) == [2, 2, 1]
    assert as_float_list("num", [1, 2.5]) == [1.0, 2.5]
    cases = [
        (lambda: as_int_list("orders", "221"), OptionTypeError,
         "orders must be a list of integers, got '221' (str)"),
        (lambda: as_int_list("orders", [2, 2], length=3, where="[identify]"), DataError,
         "[identify] orders must have 3 entries, got 2: [2, 2]"),
        (lambda: as_int_list("orders", [2, "x", 1]), OptionTypeError,
         "orders[1] must be an integer, got 'x' (str)"),
        (lambda: as_int_list("orders", [2, -1], minimum=0), DataError,
         "orders[1] must be >= 0, got -1"),
        (lambda: as_float_list("den", [], min_length=1), DataError,
         "den must have at least 1 entry, got []"),
        (lambda: as_float_list("den", 2.0), OptionTypeError,
         "den must be a list of numbers, got 2.0 (float)"),
        (lambda: as_float_list("den", [1.0, None]), OptionTypeError,
         "den[1] must be a number, got None (NoneType)"),
    ]
    for call, error, message in cases:
        with pytest.raises(error) as info:
            call()
        assert str(info.value) == message


def test_read_json(tmp_path):
    good = tmp_path / "truth.json"
    good.write_text('{"K": 1.5}', encoding="utf-8")
    assert read_json(good, "truth file") == {"K": 1.5}
    bad = tmp_path / "bad.json"
    bad.write_text("{bad", encoding="utf-8")
    with pytest.raises(FileFormatError) as info:
        read_json(bad, "truth file")
    assert str(info.value).startswith(f"truth file {bad} is not valid JSON: ")
    assert "line 1, column 2" in str(info.value)
    binary = tmp_path / "bin.json"
    binary.write_bytes(b"{\xc3(")
    with pytest.raises(FileFormatError, match=r"is not UTF-8 text: .* at byte 1 \(line 1\)"):
        read_json(binary, "truth file")
    with pytest.raises(MissingFileError, match="missing.json: no such file") as missing:
        read_json(tmp_path / "missing.json", "truth file")
    assert isinstance(missing.value, FileNotFoundError)


def test_as_array_accepts_numbers_without_copying():
    x = np.arange(3.0)
    assert as_array("x", x) is x  # a float array comes back as is: the caller must copy
    np.testing.assert_array_equal(as_array("x", [1, 2]), [1.0, 2.0])
    assert math.isnan(as_array("x", [math.nan], finite=False)[0])


@pytest.mark.parametrize(
    ("value", "kwargs", "error", "message"),
    [
        ("abc", {}, OptionTypeError, "x must be an array of real numbers, got 'abc' (str)"),
        (None, {}, OptionTypeError, "x must be an array of real numbers, got None (NoneType)"),
        (["a", 1], {}, OptionTypeError, "x must be an array of real numbers"),
        ([1j], {}, OptionTypeError, "x must hold real numbers, got complex values"),
        ([[1.0], [1.0, 2.0]], {}, DataError, "x must be a rectangular array of numbers"),
        (np.ones((2, 2)), {"ndim": 1}, DataError, "x must be 1-D, got an array of shape (2, 2)"),
        (1.0, {"ndim": 1}, DataError, "x must be 1-D, got a scalar"),
        ([1.0], {"min_size": 2}, DataError, "x needs at least 2 values, got 1"),
        ([1.0, math.inf], {}, DataError,
         "x has 1 non-finite value(s), the first (inf) at index 1; remove or interpolate them"),
    ],
)
def test_as_array_refuses(value, kwargs, error, message):
    with pytest.raises(error) as info:
        as_array("x", value, **kwargs)
    assert str(info.value).startswith(message)


def test_as_instance_as_path_as_str_list(tmp_path):
    assert as_instance("n", 3, int) == 3
    with pytest.raises(OptionTypeError, match=r"^n must be a int or float, got 'x' \(str\)$"):
        as_instance("n", "x", (int, float))
    with pytest.raises(OptionTypeError, match=r"n must be an integer count, got None"):
        as_instance("n", None, int, "an integer count")
    assert as_path("path", "a.csv").name == "a.csv"
    with pytest.raises(OptionTypeError, match=r"path must be a file path \(str or pathlib"):
        as_path("path", 3)
    with pytest.raises(DataError, match="path must be a file path, got an empty string"):
        as_path("path", " ")
    with pytest.raises(MissingFileError, match=r"nope\.csv: no such file; check the path"):
        as_path("path", tmp_path / "nope.csv", must_exist=True)
    assert as_str_list("names", ("a", "b")) == ["a", "b"]
    with pytest.raises(OptionTypeError, match="names must be a list of strings, got 'ab'"):
        as_str_list("names", "ab")
    with pytest.raises(OptionTypeError, match="names must be a list of strings"):
        as_str_list("names", ["a", 1])
