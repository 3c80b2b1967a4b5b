"""Any results file: reading it either works or is a ResultsError, and any values it holds make a safe page.

Property tests (Hypothesis, derandomized): arbitrary bytes as results.jsonl lines, and arbitrary
well-formed episodes whose numbers are anything a float can be (NaN, infinities, 1e308) and whose
strings are any text.
"""

from __future__ import annotations

import json
import tempfile
from html.parser import HTMLParser
from pathlib import Path
from typing import Any

from hypothesis import given, settings
from hypothesis import strategies as st

from agents_core.evals.compare import compare_runs
from agents_core.evals.expect import expect_success_rate
from agents_core.evals.report import render_report, write_comparison_report
from agents_core.evals.results import ResultsError, load_results

from .results_dirs import info, write_dir

_FLOATS = st.floats(allow_nan=True, allow_infinity=True) | st.sampled_from([1e308, -1e308, 5e-324, 0.0])
_TEXT = st.text(max_size=40) | st.sampled_from(["<script>alert(1)</script>", "</style><b>", "\x1b[2J", "\u202e"])


class _Tags(HTMLParser):
    def __init__(self) -> None:
        super().__init__()
        self.tags: set[str] = set()
        self.handlers: list[str] = []

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        self.tags.add(tag)
        self.handlers += [name for name, _ in attrs if name.startswith("on")]


@st.composite
def _episode(draw: Any, index: int) -> dict[str, Any]:
    return {"episode": index, "seed": draw(st.integers(-(2**63), 2**63 - 1)), "success": draw(st.booleans()),
            "reward_sum": draw(_FLOATS), "steps": draw(st.integers(0, 10**6)),
            "time_to_success_s": draw(st.none() | _FLOATS), "steps_to_success": draw(st.none() | st.integers(0, 99)),
            "wall_s": draw(_FLOATS), "ended": draw(st.text(min_size=1, max_size=20)), "reason": draw(st.none() | _TEXT),
            "rewards": draw(st.lists(_FLOATS, max_size=30)), "frames": draw(st.lists(_TEXT, max_size=3))}


@settings(derandomize=True, database=None, max_examples=150, deadline=None)
@given(st.lists(st.binary(max_size=200) | st.text(max_size=200).map(str.encode), max_size=5), st.booleans())
def test_any_bytes_read_as_results_or_a_results_error(lines: list[bytes], newline_at_end: bool) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        out = write_dir(Path(tmp) / "run", info(), [line.replace(b"\n", b" ") for line in lines],
                        newline_at_end=newline_at_end)
        try:
            results = load_results(out)
        except ResultsError as exc:
            assert "results.jsonl, line " in str(exc)
        else:
            assert results.n <= len(lines)


@settings(derandomize=True, database=None, max_examples=60, deadline=None)
@given(st.data())
def test_any_values_make_a_page_without_markup_from_the_results(data: Any) -> None:
    n = data.draw(st.integers(0, 6))
    episodes = [data.draw(_episode(i)) for i in range(n)]
    name = data.draw(_TEXT)
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "run"
        # json.dumps writes NaN / Infinity as Python's json module does (what a runner would write).
        write_dir(out, info(name=name, world=data.draw(_TEXT), episodes=n), [json.dumps(e) for e in episodes])
        results = load_results(out)
        assert results.n == n
        page = render_report(results)
        tags = _Tags()
        tags.feed(page)
        assert "script" not in tags.tags and "b" not in tags.tags and not tags.handlers
        if n:
            compare_runs(results, results)
            write_comparison_report(results, results, Path(tmp) / "cmp.html")
            try:
                expect_success_rate(results, 0.5)
            except AssertionError as exc:
                assert "success rate" in str(exc)
