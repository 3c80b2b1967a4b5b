"""The launcher reads what a component process (and anything that process runs) writes on its report pipe.

A report line is bounded, a line that is not a JSON object is ignored, and the reader keeps
reading: a hostile or broken child cannot stop its own state reports, nor make the launcher hold
an unbounded line.
"""

from __future__ import annotations

import io
import json
from types import SimpleNamespace
from typing import Any

from agents_core.launch.supervisor import MAX_REPORT_CHARS, ChildProcess


def _child() -> ChildProcess:
    spec: Any = SimpleNamespace(component_name="vision")
    return ChildProcess(spec)


def test_hostile_lines_are_skipped_and_the_next_report_still_counts() -> None:
    child = _child()
    lines = [
        '"state"',                                      # JSON, not an object: once stopped the reader
        "[1, 2, 3]",
        "42",
        "not json at all",
        "{" + "x" * (MAX_REPORT_CHARS * 3),              # one huge line with no end in sight
        json.dumps({"state": "inactive", "error": "e" * 5000}),
        json.dumps({"state": "active"}),
    ]
    child._read_reports(io.StringIO("\n".join(lines) + "\n"))
    assert child.state == "active"
    assert child.error is not None and len(child.error) == 2000  # kept, cut to its limit


def test_an_over_long_report_is_skipped_whole_not_read_in_pieces() -> None:
    child = _child()
    # A long line whose tail looks like a report: a reader cutting it into pieces would take the tail.
    tail = json.dumps({"state": "failed"})
    long_line = " " * (MAX_REPORT_CHARS * 2) + tail
    child._read_reports(io.StringIO(long_line + "\n" + json.dumps({"state": "active"}) + "\n"))
    assert child.state == "active"
    child._read_reports(io.StringIO(long_line + "\n"))
    assert child.state == "active"  # the tail of the long line did not count
