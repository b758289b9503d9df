"""The simulator's input line splitter: CR, LF and CR LF ends, and a bounded buffer."""

from __future__ import annotations

import pytest

from gelrig.simulators.mcr501.lines import TOO_LONG, LineSplitter


def test_cr_lf_and_cr_lf_end_lines_and_empty_lines_are_skipped() -> None:
    s = LineSplitter(16)
    assert s.feed(b"A[?]\rB[?]\nC[?]\r\n\r\n") == [b"A[?]", b"B[?]", b"C[?]"]
    assert s.feed(b"D[") == []
    assert s.pending == 2
    assert s.feed(b"?]\r") == [b"D[?]"]
    assert s.feed(b"\n") == []  # the LF of a CR LF split across two reads


def test_the_buffer_never_holds_more_than_the_bound() -> None:
    s = LineSplitter(8)
    out: list[bytes | None] = []
    for _ in range(1000):
        out += s.feed(b"x" * 7)
        assert s.pending <= 8
    assert out == [TOO_LONG]  # reported once, however long the line
    assert s.feed(b"tail\rOK[]\n") == [b"OK[]"]  # the rest of the long line is dropped


def test_a_line_of_exactly_the_bound_is_kept() -> None:
    s = LineSplitter(4)
    assert s.feed(b"abcd\nabcde\nab") == [b"abcd", TOO_LONG]
    assert s.feed(b"c\n") == [b"abc"]


def test_the_bound_must_be_positive() -> None:
    with pytest.raises(ValueError):
        LineSplitter(0)
