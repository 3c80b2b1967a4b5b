"""The HTML report as a document: self-contained, escaped, its figures those of the results, robust to odd runs.

The page is parsed with the standard library's HTML parser (what a browser's tokenizer sees);
tests/evals/test_report_browser.py opens it in Chromium.
"""

from __future__ import annotations

import base64
import json
import re
from html.parser import HTMLParser
from pathlib import Path
from typing import Any

import pytest

from agents_core.evals.compare import compare_runs
from agents_core.evals.report import MAX_EPISODES_SHOWN, write_comparison_report, write_report
from agents_core.evals.results import load_results
from agents_core.evals.stats import wilson_interval

from .results_dirs import episode, info, make_run, png, write_dir

HOSTILE = '<script>window.__pwned = 1</script><img src=x onerror="window.__pwned = 2">"\'&</td></table></style>'


class _Page(HTMLParser):
    """Every start tag with its attributes, and the text, as a browser's tokenizer reads them."""

    def __init__(self) -> None:
        super().__init__(convert_charrefs=True)
        self.tags: list[tuple[str, dict[str, str | None]]] = []
        self.text: list[str] = []
        self.by_id: dict[str, dict[str, str | None]] = {}

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        attributes = dict(attrs)
        self.tags.append((tag, attributes))
        if attributes.get("id"):
            self.by_id[str(attributes["id"])] = attributes

    def handle_data(self, data: str) -> None:
        self.text.append(data)


def _parse(path: Path) -> tuple[str, _Page]:
    source = path.read_text(encoding="utf-8")
    page = _Page()
    page.feed(source)
    page.close()
    return source, page


def _assert_self_contained(source: str, page: _Page) -> None:
    names = {tag for tag, _ in page.tags}
    assert not names & {"script", "link", "iframe", "object", "embed", "base", "form", "audio", "video", "source"}
    for tag, attributes in page.tags:
        for name, value in attributes.items():
            assert not name.startswith("on"), (tag, name)  # no event handler
            if name in ("src", "href", "xlink:href", "action", "srcset", "poster", "data"):
                assert (value or "").startswith("data:image/"), (tag, name, (value or "")[:60])
    style = "".join(re.findall(r"<style>(.*?)</style>", source, re.S))
    assert "url(" not in style and "@import" not in style and "@font-face" not in style
    csp = next(a for t, a in page.tags if t == "meta" and a.get("http-equiv") == "Content-Security-Policy")
    assert "default-src 'none'" in (csp["content"] or "")


def test_report_is_self_contained_and_shows_the_results_figures(tmp_path: Path) -> None:
    out = make_run(tmp_path / "run", [True] * 16 + [False] * 4)
    path = write_report(out)
    assert path == out / "report.html"
    source, page = _parse(path)
    _assert_self_contained(source, page)
    low, high = wilson_interval(16, 20)
    assert page.by_id["rate"]["data-rate"] == repr(0.8)
    assert (float(page.by_id["interval"]["data-low"] or ""), float(page.by_id["interval"]["data-high"] or "")) == \
        (low, high)
    text = " ".join(page.text)
    assert "16/20" in text and "80.0 %" in text and f"{low * 100:.1f} %" in text and f"{high * 100:.1f} %" in text
    for word in ("Reacher-v5", "examples/reacher_expert.py", "lockstep", "0.7.0", "50 steps, 60 s wall time",
                 "finished: all 20 episodes", "fingertip within 2 cm"):
        assert word in text, word
    assert source.count("<svg") >= 4  # the interval, the reward curves, the time-to-success and reward strips
    assert source.count('<polyline class="line ok"') == 16 and source.count('<polyline class="line fail"') == 4
    # The filmstrip embeds the first failed and the first successful episode's frames as they are on disk.
    results = load_results(out)
    failed = next(e for e in results.episodes if not e.success)
    frame = (out / failed.frames[1]).read_bytes()
    assert f"data:image/png;base64,{base64.b64encode(frame).decode()}" in source
    assert sum(1 for tag, a in page.tags if tag == "img") == 8


def test_every_episode_has_a_row_with_its_values(tmp_path: Path) -> None:
    out = make_run(tmp_path / "run", [True, False, True, False, False], seeds=[7, 3, 99, 12, 5])
    source, _ = _parse(write_report(out))
    rows = re.findall(r'<td class="num" data-field="seed">(\d+)</td><td data-field="success">.*?>(yes|no)<', source)
    assert rows == [("7", "yes"), ("3", "no"), ("99", "yes"), ("12", "no"), ("5", "no")]
    for e in load_results(out).episodes:
        assert f'data-field="reward_sum">{e.reward_sum:.4g}<' in source


def test_strings_from_the_results_are_escaped_everywhere(tmp_path: Path) -> None:
    out = write_dir(tmp_path / "run", info(name=HOSTILE, world=HOSTILE, recipe=HOSTILE, success_rule=HOSTILE,
                                           agents_core_version=HOSTILE, transport=HOSTILE, clock=HOSTILE),
                    [episode(0, False, ended=HOSTILE[:60], reason=HOSTILE, frames=[HOSTILE]), episode(1, True)])
    source, page = _parse(write_report(out))
    _assert_self_contained(source, page)
    assert "<script" not in source and "onerror=" not in source.replace("onerror=&quot;", "")
    assert sum(HOSTILE in chunk for chunk in page.text) >= 7  # shown as text, as it was written
    assert sum(1 for tag, _ in page.tags if tag == "img") == 0  # the frame "path" is no image


def test_missing_odd_and_outside_frames_show_as_missing(tmp_path: Path) -> None:
    out = tmp_path / "run"
    (out / "frames").mkdir(parents=True)
    good = png(8, 6, lambda x, y: (x * 30, y * 40, 90))
    (out / "frames" / "ok.png").write_bytes(good)
    (out / "frames" / "text.png").write_text("not an image")
    (out / "frames" / "big.png").write_bytes(good + b"\x00" * (3 * 1024 * 1024))
    (tmp_path / "outside.png").write_bytes(good)
    (out / "frames" / "link.png").symlink_to(tmp_path / "outside.png")
    frames = ["frames/ok.png", "frames/gone.png", "frames/text.png", "frames/big.png", "../outside.png",
              str(tmp_path / "outside.png"), "frames/link.png", "/etc/passwd"]
    write_dir(out, info(), [episode(0, False, frames=frames), episode(1, True, frames=[])])
    source, page = _parse(write_report(out))
    images = [a["src"] for tag, a in page.tags if tag == "img"]
    assert images == [f"data:image/png;base64,{base64.b64encode(good).decode()}"]
    assert source.count("frame missing") == 7
    assert "This episode has no frames." in source


def test_an_interrupted_run_is_reported_as_such(tmp_path: Path) -> None:
    whole = json.dumps(episode(2, True))
    out = write_dir(tmp_path / "run", info(episodes=10, finished=None, interrupted=True),
                    [episode(0, True), episode(1, False), whole[:40]], newline_at_end=False)
    _, page = _parse(write_report(out))
    text = " ".join(page.text)
    assert "interrupted: 2 of 10 episodes finished" in text and "This run did not finish" in text
    assert "cut short" in text and page.by_id["successes"]["data-n"] == "2"


@pytest.mark.parametrize("lines", [
    [],
    [episode(0, False, rewards=[], steps=0, ended="world_died", reason="the world process exited with -9")],
    [episode(0, False, rewards=[float("nan")] * 3, reward_sum=float("nan"), ended="error", reason="NaN")],
    [episode(i, True, rewards=[0.5]) for i in range(3)],
])
def test_odd_runs_still_make_a_page(tmp_path: Path, lines: list[dict[str, Any]]) -> None:
    out = write_dir(tmp_path / "run", info(episodes=3), lines)
    source, page = _parse(write_report(out))
    _assert_self_contained(source, page)
    assert page.by_id["successes"]["data-n"] == str(len(lines))
    if not lines:
        assert "no episode finished" in source and "No successful episode." in source


def test_a_long_run_shows_a_bounded_table(tmp_path: Path) -> None:
    n = MAX_EPISODES_SHOWN + 500
    out = write_dir(tmp_path / "run", info(episodes=n), [episode(i, i % 3 == 0, steps=5) for i in range(n)])
    path = write_report(out)
    source = path.read_text()
    assert source.count('data-field="seed"') == MAX_EPISODES_SHOWN and f"of {n} episodes" in source
    assert source.count("<polyline") == 200
    assert path.stat().st_size < 2_000_000


def test_write_report_rewrites_atomically_and_can_go_elsewhere(tmp_path: Path) -> None:
    out = make_run(tmp_path / "run", [True, False], frames=False)
    first = write_report(out).read_text()
    other = write_report(out, path=tmp_path / "elsewhere" / "r.html")
    assert other.read_text().split("<footer>")[0] == first.split("<footer>")[0]
    assert sorted(p.name for p in out.iterdir()) == ["evaluation.json", "report.html", "results.jsonl"]


def test_comparison_page_shows_both_runs_and_the_verdict(tmp_path: Path) -> None:
    a = make_run(tmp_path / "a", [True] * 16 + [False] * 4, name="expert")
    b = make_run(tmp_path / "b", [True] * 5 + [False] * 15, name=HOSTILE)
    path = write_comparison_report(a, b, tmp_path / "cmp" / "compare.html")
    source, page = _parse(path)
    _assert_self_contained(source, page)
    comparison = compare_runs(a, b)
    assert comparison.verdict == "worse"
    assert page.by_id["verdict"]["data-verdict"] == "worse"
    assert float(page.by_id["p-value"]["data-p"] or "") == comparison.p_value
    assert "run-a" in page.by_id and "run-b" in page.by_id
    text = " ".join(page.text)
    assert "16/20" in text and "5/20" in text and "B is worse than A" in text
    # Seeds 5-15 succeeded in A and failed in B.
    assert text.count("yes") >= 11 and "<script" not in source
