"""How TextToSpeech cuts an utterance into pieces: the first clause on its own, then sentences
(:func:`agents_core.engines.local_tts.split_speakable`), whatever the chunks a stream arrives in."""

from __future__ import annotations

from hypothesis import given, settings
from hypothesis import strategies as st

from agents_core.engines.local_tts import split_sentences, split_speakable

ANSWER = "The red cube is on the table, next to the window. I will drive there, then pick it up. Done."


def test_the_first_clause_is_a_piece_when_long_enough() -> None:
    assert split_speakable(ANSWER, first=True, min_clause_words=4) == (
        ["The red cube is on the table,", "next to the window.", "I will drive there, then pick it up."], "Done.")
    # Not first: sentences only; later clauses never split.
    assert split_speakable(ANSWER, first=False, min_clause_words=4) == split_sentences(ANSWER)


def test_short_fragments_wait_for_more() -> None:
    assert split_speakable("Well, the cube is red", first=True, min_clause_words=4) == ([], "Well, the cube is red")
    assert split_speakable("Well, the cube is red, I think", first=True, min_clause_words=4) == (
        ["Well, the cube is red,"], "I think")
    # A sentence that ends before any long enough clause is the first piece, as before.
    assert split_speakable("Yes, sure. The cube, I mean", first=True, min_clause_words=4) == (
        ["Yes, sure."], "The cube, I mean")


def test_incomplete_clauses_and_numbers_stay_whole() -> None:
    assert split_speakable("It costs about 3,000 dollars", first=True, min_clause_words=2) == (
        [], "It costs about 3,000 dollars")
    # No white space after the comma yet: the next chunk may continue the number.
    assert split_speakable("We will need about 3,", first=True, min_clause_words=2) == ([], "We will need about 3,")
    assert split_speakable("At 10:30 we leave; bring it", first=True, min_clause_words=3) == (
        ["At 10:30 we leave;"], "bring it")


def test_zero_turns_clauses_off() -> None:
    assert split_speakable(ANSWER, first=True, min_clause_words=0) == split_sentences(ANSWER)


def _stream(chunks: list[str], min_words: int) -> list[str]:
    """What the component queues for one streamed utterance (text_to_speech.py's _take_text)."""
    pieces: list[str] = []
    pending = ""
    for chunk in chunks:
        got, pending = split_speakable(pending + chunk, first=not pieces, min_clause_words=min_words)
        pieces += got
    return pieces + ([pending.strip()] if pending.strip() else [])


_WORDS = st.sampled_from(["the", "red", "cube", "3,000", "10:30", "3.5", "is", "a", "Well", "on", "table", "I"])
_MARKS = st.sampled_from(["", "", "", ",", ".", "!", "?", ";", ":"])
_SPACES = st.sampled_from([" ", " ", "  ", "\n"])
_TEXT = st.lists(st.tuples(_WORDS, _MARKS, _SPACES), max_size=40).map(
    lambda parts: "".join(w + m + s for w, m, s in parts))


@settings(max_examples=300, deadline=None)
@given(text=_TEXT, cuts=st.lists(st.integers(0, 400), max_size=12), min_words=st.integers(0, 6))
def test_any_chunking_speaks_the_whole_text_once_in_order(text: str, cuts: list[int], min_words: int) -> None:
    bounds = sorted({min(c, len(text)) for c in cuts})
    chunks = [text[a:b] for a, b in zip([0, *bounds], [*bounds, len(text)], strict=True)]
    pieces = _stream(chunks, min_words)
    # Nothing dropped, repeated or reordered: only white space between pieces goes.
    assert "".join("".join(pieces).split()) == "".join(text.split())
    assert all(p == p.strip() and p for p in pieces)
    # The pieces do not depend on how the stream was chunked.
    assert pieces == _stream([text], min_words)
    # Only the first piece may be a clause; the rest are what split_sentences makes of the remainder.
    if pieces:
        tail = text.split(pieces[0], 1)[1]
        assert pieces[1:] == _stream([tail], 0)
