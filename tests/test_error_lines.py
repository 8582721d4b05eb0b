"""An error message stays one short line however long the input it quotes back
(issue #28: `sim friction --mu` with 10,000 values printed a 60 KB line)."""

from __future__ import annotations

from hypothesis import given
from hypothesis import strategies as st

from snakebot.errors import LINE_LIMIT, QUOTE_LIMIT, WORD_LIMIT, bounded_line, quoted


def test_a_short_value_is_quoted_as_repr_would() -> None:
    for value in ["0.1,1,10", "", "it's", "x" * QUOTE_LIMIT]:
        assert quoted(value) == repr(value)
    assert quoted([1, 2]) == "[1, 2]"


def test_a_long_value_shows_its_start_end_and_length() -> None:
    values = ",".join(["0.5"] * 10_000)
    shown = quoted(values)
    assert shown.startswith("'0.5,0.5,") and "...' (" not in shown
    assert shown.endswith(f",0.5' ({len(values):,} characters)"), shown
    assert len(shown) <= QUOTE_LIMIT + 10, shown


def test_a_long_path_keeps_its_punctuation_and_the_message_its_ends() -> None:
    path = "/tmp/" + "d" * 20_000
    line = bounded_line(f"could not open {path}: [Errno 36] File name too long: {path!r}")
    assert len(line) <= LINE_LIMIT
    assert line.startswith("could not open /tmp/ddd") and line.endswith("characters)"), line
    assert "(20,005 characters): [Errno 36] File name too long: '/tmp/" in line, line


def test_a_line_that_is_short_enough_is_left_alone() -> None:
    text = "x" * WORD_LIMIT + " " + "y" * (LINE_LIMIT - WORD_LIMIT - 1)
    assert bounded_line(text) == text


@given(
    words=st.lists(
        st.text(st.sampled_from("ab ,.:'x/"), max_size=3000) | st.sampled_from(["give 1..9"]),
        max_size=8,
    ),
    limit=st.sampled_from([80, 200, LINE_LIMIT]),
)
def test_any_message_is_bounded_and_keeps_its_start(words: list[str], limit: int) -> None:
    text = " ".join(words)
    line = bounded_line(text, limit)
    assert len(line) <= limit
    assert line.startswith(text[:10].rstrip()), (text[:40], line)
