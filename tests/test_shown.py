"""A long value in a message keeps its tail, where a path's damage sits."""

from servoid._shown import shown


def test_a_long_path_keeps_the_file_name_and_says_its_length():
    path = "/tmp/" + "d" * 200 + "/ta\x00nks.py"
    text = shown(path)
    assert text.startswith("'/tmp/ddd") and "ta\\x00nks.py'" in text  # the NUL stays in view
    assert text.endswith(f"({len(repr(path))} characters)")
    assert len(text) < 100  # a line of a message, not the whole value


def test_a_short_value_is_its_repr_and_a_huge_integer_is_named():
    assert shown("abc") == "'abc'"
    assert shown(10 ** 5000) == "an integer of more than 4300 digits"
