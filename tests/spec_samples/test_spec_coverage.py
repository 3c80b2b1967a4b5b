"""Every ```python block of the spec is run by a test of tests/spec_samples/, none silently skipped.

The tests name the blocks they run (``@covers``); this checks the mapping against the spec file
itself: every block number has a test, each test's expected first line is still its block's (a
changed spec fails here, not silently elsewhere), and no test names a block that does not exist.
"""

from __future__ import annotations

from . import test_spec_clients, test_spec_components, test_spec_messages  # noqa: F401 - they fill COVERED
from .spec_blocks import COVERED, SPEC, spec_blocks


def test_every_python_block_of_the_spec_has_a_test() -> None:
    blocks = spec_blocks()
    assert len(blocks) >= 30, f"{SPEC} has only {len(blocks)} python blocks: is it the spec?"
    missing = [(b.number, b.line, b.first_line) for b in blocks if b.number not in COVERED]
    assert not missing, f"spec blocks without a test (number, line, first line): {missing}"
    unknown = sorted(set(COVERED) - {b.number for b in blocks})
    assert not unknown, f"tests name blocks the spec does not have: {unknown}"


def test_each_test_runs_the_block_it_names() -> None:
    by_number = {b.number: b for b in spec_blocks()}
    wrong = [(number, test, expected, by_number[number].first_line) for number, (test, expected) in COVERED.items()
             if number in by_number and by_number[number].first_line != expected]
    assert not wrong, f"(block, test, expected first line, actual first line): {wrong}"
