"""The cell's JSON messages and params files read without a way to break the reader
(rheo_shaping.params.wire): bounded length and depth, finite numbers, known keys."""
from __future__ import annotations

import math

import pytest

from rheo_shaping.params.wire import Field, WireError, check_depth, load_json, read_fields

FIELDS = {"state": Field(str, max_len=8), "transitions": Field(int, 0, 100),
          "x": Field(float, -1.0, 1.0)}


def test_a_deep_message_is_refused_before_any_parser_recurses():
    """100,000 '[' made json.loads raise RecursionError in every node."""
    with pytest.raises(WireError):
        load_json("[" * 100_000)                  # longer than MAX_CHARS, too
    with pytest.raises(WireError, match="nests deeper than 8 levels"):
        load_json("[" * 100_000, max_chars=200_000)
    assert load_json("[" * 8 + "]" * 8) == [[[[[[[[]]]]]]]]
    with pytest.raises(WireError, match="deeper than 8"):
        load_json("[" * 9 + "]" * 9)


def test_brackets_inside_strings_do_not_count_as_depth():
    assert load_json('{"a": "[[[[[[[[[[[[\\"{{{{{{{{{{"}') == {"a": '[[[[[[[[[[[["{{{{{{{{{{'}
    check_depth('"[[[[\\\\" [1]', 1)          # an escaped backslash ends before the quote
    with pytest.raises(WireError):
        check_depth('"\\\\" [[1]]', 1)


@pytest.mark.parametrize("text", ['{"x": Infinity}', '{"x": NaN}', '{"x": -Infinity}',
                                  '{"x": 1e400}', '[1e999]'])
def test_non_finite_numbers_are_refused(text):
    """An infinite 'transitions' crashed the lifecycle manager on int()."""
    with pytest.raises(WireError):
        load_json(text)


def test_length_and_garbage_are_refused_with_the_reason():
    with pytest.raises(WireError, match="100001 characters, more than 100000"):
        load_json("1" * 100_001, max_chars=100_000)
    with pytest.raises(WireError, match="not JSON"):
        load_json("{'a': 1}")
    with pytest.raises(WireError, match="not JSON"):
        load_json("9" * 5000)              # over Python's digit limit for int()
    with pytest.raises(WireError, match="not text"):
        load_json(b"{}")


def test_read_fields_takes_exactly_the_keys_with_their_types_and_ranges():
    assert read_fields('{"state": "active", "transitions": 3, "x": 0}', FIELDS) == \
        {"state": "active", "transitions": 3, "x": 0.0}
    for text, why in (('{"state": "a", "transitions": 3}', "missing: x"),
                      ('{"state": "a", "transitions": 3, "x": 0, "y": 1}', "unknown: y"),
                      ('{"state": 1, "transitions": 3, "x": 0}', "state = '1': expected str"),
                      ('{"state": "a", "transitions": 3.5, "x": 0}', "expected int"),
                      ('{"state": "a", "transitions": true, "x": 0}', "expected int"),
                      ('{"state": "a", "transitions": 101, "x": 0}', r"within \[0, 100\]"),
                      ('{"state": "a", "transitions": 1, "x": -2}', r"within \[-1, 1\]"),
                      ('{"state": "toolongstate", "transitions": 1, "x": 0}', "12 characters"),
                      ('[1, 2]', "not a JSON object")):
        with pytest.raises(WireError, match=why):
            read_fields(text, FIELDS)
    assert math.isfinite(read_fields('{"state": "", "transitions": 0, "x": 1}', FIELDS)["x"])
