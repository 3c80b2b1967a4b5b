"""The evaluation report: one self-contained HTML file, readable offline and safe to open whatever the results hold.

:func:`write_report` turns an output directory into ``report.html``: what was evaluated (world,
recipe, transport, clock, seeds, limits, version, finished or not), the success rate with its 95 %
Wilson interval, the reward sums and times to success with their intervals, a reward curve per
episode, the times to success as a strip, a filmstrip of one failed and one successful episode and
a table of every episode. :func:`write_comparison_report` puts two evaluations side by side with the
verdict of :func:`~agents_core.evals.compare.compare_runs`.

The page needs nothing but itself: the style sheet is inline, the charts are inline SVG
(:mod:`agents_core.evals.svg`), the frames are ``data:`` URIs, and there is no script at all. Every
string from the results is escaped, and the page's Content-Security-Policy allows no script, no
connection and no image but ``data:`` ones, so a reason reading ``<script>`` shows as text, and even
a mistake in escaping could not run it or make the page fetch anything.
"""

from __future__ import annotations

import base64
import datetime as _dt
import html
import math
import os
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from .compare import Comparison, compare_runs
from .results import EpisodeResult, EvaluationResults, ResultsError, load_results, read_capped
from .stats import mean_interval, wilson_interval
from .svg import Series, interval_chart, line_chart, strip_chart

__all__ = ["REPORT_FILE", "render_comparison", "render_report", "write_comparison_report", "write_report"]

#: The report's name inside the output directory.
REPORT_FILE = "report.html"
#: At most this many episodes get a reward curve and a table row (results.jsonl keeps them all).
MAX_EPISODES_SHOWN = 2000
MAX_CURVES = 200
#: Frames shown per episode of the filmstrip.
MAX_FILMSTRIP_FRAMES = 8
#: Longest reason shown in a table cell.
MAX_REASON_CHARS = 300

_CSP = "default-src 'none'; img-src data:; style-src 'unsafe-inline'; base-uri 'none'; form-action 'none'"
_STYLE = """
body{font-family:system-ui,-apple-system,"Segoe UI",Roboto,sans-serif;margin:24px auto;max-width:1320px;
 padding:0 16px;color:#1d2733;background:#fff;line-height:1.4}
h1{font-size:1.5em;margin:0 0 4px}h2{font-size:1.15em;margin:28px 0 8px;border-bottom:1px solid #dde3ea;
 padding-bottom:4px}
table{border-collapse:collapse;font-size:.9em}td,th{padding:3px 10px;border-bottom:1px solid #eef1f4;
 text-align:left;vertical-align:top;unicode-bidi:isolate}th{background:#f5f7f9}
table.info th{width:11em}td.num{text-align:right;font-variant-numeric:tabular-nums}
.headline{font-size:1.4em;margin:8px 0}.headline .muted{white-space:nowrap}
.muted{color:#66717d}.note{background:#fff6df;border-left:4px solid #e8b200;
 padding:6px 10px;margin:8px 0}
.yes{color:#17803d;font-weight:600}.no{color:#c0392b;font-weight:600}
.chart{max-width:100%;height:auto;font-size:11px}.chart .axis{stroke:#7b8794}.chart .tick{stroke:#7b8794}
.chart .grid{stroke:#eef1f4}.chart text{fill:#3d4852}.chart .xt{text-anchor:middle}
.chart .yt,.chart .rl{text-anchor:end;dominant-baseline:middle}.chart .xl{text-anchor:middle}
.chart .yl{text-anchor:middle}.chart .line{fill:none;stroke-width:1.3;stroke-opacity:.6}
.chart .line.ok{stroke:#17803d}.chart .line.fail{stroke:#c0392b}.chart .dot.ok{fill:#17803d}
.chart .dot.fail{fill:#c0392b}.chart .median{stroke:#1d2733;stroke-width:2}
.chart .ci{stroke-width:4;stroke-linecap:round}.chart .ci.a,.chart .dot.a{stroke:#2b6cb0;fill:#2b6cb0}
.chart .ci.b,.chart .dot.b{stroke:#b7791f;fill:#b7791f}.chart .ci.ok{stroke:#17803d}
.film{display:flex;gap:6px;flex-wrap:wrap;margin:4px 0 12px}.film figure{margin:0;text-align:center;
 font-size:.8em;color:#66717d}.film img{display:block;width:148px;height:auto;border:1px solid #dde3ea;
 image-rendering:auto}.film .missing{width:148px;height:111px;display:flex;align-items:center;
 justify-content:center;background:#f5f7f9;border:1px dashed #b8c2cc}
.side{display:grid;grid-template-columns:1fr 1fr;gap:24px}
.two{display:grid;grid-template-columns:repeat(auto-fit,minmax(540px,1fr));gap:8px 32px}
.verdict{font-size:1.3em;padding:8px 12px;
 border-radius:4px;display:inline-block}.verdict.worse{background:#fde8e6;color:#9b2c1f}
.verdict.better{background:#e3f6ea;color:#17803d}.verdict.same{background:#eef1f4}
footer{margin-top:32px;font-size:.8em;color:#66717d}
"""


#: Shown for a value that is not there, and between an interval's bounds (an en dash).
_DASH = "\u2013"


def _e(value: object) -> str:
    return html.escape(str(value), quote=True)


def _pct(rate: float) -> str:
    return f"{rate * 100:.1f} %"


def _num(value: float | None, digits: int = 4) -> str:
    if value is None:
        return _DASH
    if not math.isfinite(value):
        return str(value)
    return f"{value:.{digits}g}"


def _yes_no(flag: bool) -> str:
    return '<span class="yes">yes</span>' if flag else '<span class="no">no</span>'


def _page(title: str, body: str) -> str:
    made = _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    return (f'<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">'
            f'<meta http-equiv="Content-Security-Policy" content="{_CSP}">'
            f'<meta name="viewport" content="width=device-width, initial-scale=1">'
            f"<title>{_e(title)}</title><style>{_STYLE}</style></head>\n<body>{body}"
            f'<footer>Written by agents_core.evals.report on {_e(made)}. This page is self-contained: '
            f"it loads nothing and runs no script.</footer></body></html>\n")


def _table(headers: Sequence[str], rows: Sequence[Sequence[str]], css: str = "") -> str:
    """A table: ``headers`` are escaped here; each row is a list of cells (``<td>``, ``<th>``) built and escaped."""
    head = "".join(f"<th>{_e(h)}</th>" for h in headers)
    body = "".join(f"<tr>{''.join(row)}</tr>" for row in rows)
    return f'<table class="{css}"><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>'


def _status(results: EvaluationResults) -> str:
    info = results.info
    if info.interrupted:
        text = f"interrupted: {results.n} of {info.episodes} episodes finished"
    elif info.finished is None:
        text = (f"not finished: {results.n} of {info.episodes} episodes so far (the run is still going, or "
                "was stopped without finishing its files)")
    elif results.n < info.episodes:
        text = f"finished with {results.n} of {info.episodes} episodes"
    else:
        text = f"finished: all {info.episodes} episodes"
    return text


def _seeds_text(seeds: Sequence[int]) -> str:
    if not seeds:
        return _DASH
    if len(seeds) > 2 and list(seeds) == list(range(seeds[0], seeds[0] + len(seeds))):
        return f"{seeds[0]}{_DASH}{seeds[-1]} ({len(seeds)} seeds)"
    shown = ", ".join(str(s) for s in seeds[:40])
    return shown + (f", … ({len(seeds)} seeds)" if len(seeds) > 40 else "")


def _info_section(results: EvaluationResults) -> str:
    info = results.info
    limits = ", ".join(part for part in (
        f"{info.max_steps} steps" if info.max_steps is not None else "",
        f"{_num(info.max_wall_s)} s wall time" if info.max_wall_s is not None else "") if part) or "none"
    rows = [("world", info.world), ("recipe", info.recipe), ("transport", info.transport), ("clock", info.clock),
            ("success rule", info.success_rule), ("episodes asked", str(info.episodes)),
            ("seeds", _seeds_text(info.seeds)), ("limits", limits), ("started", info.started),
            ("finished", info.finished or _DASH), ("status", _status(results)),
            ("agents_core", info.agents_core_version), ("results", str(results.out_dir))]
    body = "".join(f'<tr><th>{_e(k)}</th><td data-field="{_e(k)}">{_e(v or _DASH)}</td></tr>' for k, v in rows)
    notes = ""
    if results.info.interrupted or results.info.finished is None:
        notes += f'<p class="note">This run did not finish: {_e(_status(results))}. The figures below are ' \
                 "for the episodes that did.</p>"
    if results.partial_last_line:
        notes += ('<p class="note">The last line of results.jsonl was cut short (the run stopped while writing '
                  "it); that episode is not counted.</p>")
    return f'<table class="info"><tbody>{body}</tbody></table>{notes}'


def _headline(results: EvaluationResults) -> str:
    low, high = wilson_interval(results.successes, results.n)
    ended = Counter(e.ended for e in results.episodes)
    ended_text = ", ".join(f"{_e(word)} {count}" for word, count in ended.most_common()) or "no episode finished"
    return (f'<p class="headline">Success: <strong id="successes" data-successes="{results.successes}" '
            f'data-n="{results.n}">{results.successes}/{results.n}</strong> = <strong id="rate" '
            f'data-rate="{results.success_rate!r}">{_pct(results.success_rate)}</strong> '
            f'<span class="muted">(95 % interval <span id="interval" data-low="{low!r}" data-high="{high!r}">'
            f"{_pct(low)} {_DASH} {_pct(high)}</span>)</span></p>"
            f'<p class="muted">Ended: {ended_text}</p>')


def _figures_section(results: EvaluationResults) -> str:
    episodes = results.episodes
    rewards = mean_interval(e.reward_sum for e in episodes)
    times = mean_interval(e.time_to_success_s for e in episodes if e.success and e.time_to_success_s is not None)
    steps_to = mean_interval(float(e.steps_to_success) for e in episodes
                             if e.success and e.steps_to_success is not None)
    steps = mean_interval(float(e.steps) for e in episodes)
    wall = mean_interval(e.wall_s for e in episodes)
    rows = [("reward sum", rewards, ""), ("time to success (successes)", times, " s"),
            ("steps to success (successes)", steps_to, ""), ("steps per episode", steps, ""),
            ("wall time per episode", wall, " s")]
    cells = []
    for name, m, unit in rows:
        mean = _DASH if m.mean is None else f"{_num(m.mean)}{unit}"
        interval = _DASH if m.low is None or m.high is None else f"{_num(m.low)} {_DASH} {_num(m.high)}{unit}"
        median = _DASH if m.median is None else f"{_num(m.median)}{unit}"
        extra = f" ({m.non_finite} NaN or infinite left out)" if m.non_finite else ""
        cells.append([f"<th>{_e(name)}</th>", f'<td class="num">{_e(mean + extra)}</td>',
                      f'<td class="num">{_e(interval)}</td>', f'<td class="num">{_e(median)}</td>',
                      f'<td class="num">{m.n}</td>'])
    return _table(["", "mean", "95 % interval", "median", "n"], cells, "figures")


def _cumulative(rewards: Sequence[float]) -> list[float]:
    total, out = 0.0, []
    for r in rewards:
        total += r
        out.append(total)
    return out


@dataclass(frozen=True)
class _Scales:
    """Values the charts of a run must cover, so that two runs side by side are drawn on the same scales."""

    steps: tuple[float, ...] = ()
    cumulative: tuple[float, ...] = ()
    times: tuple[float, ...] = ()
    reward_sums: tuple[float, ...] = ()

    @staticmethod
    def of(*runs: EvaluationResults) -> _Scales:
        """The extremes of ``runs``' drawn values."""
        def ends(values: list[float]) -> tuple[float, ...]:
            finite = [v for v in values if math.isfinite(v)]
            return (min(finite), max(finite)) if finite else ()

        shown = [e for run in runs for e in run.episodes[:MAX_CURVES]]
        return _Scales(steps=ends([float(len(e.rewards) - 1) for e in shown if e.rewards]),
                       cumulative=ends([v for e in shown for v in _cumulative(e.rewards)]),
                       times=ends([e.time_to_success_s for run in runs for e in run.episodes
                                   if e.success and e.time_to_success_s is not None]),
                       reward_sums=ends([e.reward_sum for run in runs for e in run.episodes]))


def _curves_section(results: EvaluationResults, width: int = 640, scales: _Scales | None = None) -> str:
    scales = scales or _Scales()
    shown = results.episodes[:MAX_CURVES]
    series = []
    for e in shown:
        cumulative = _cumulative(e.rewards)
        series.append(Series(f"episode {e.episode} (seed {e.seed}): {'success' if e.success else e.ended}, "
                             f"reward sum {_num(e.reward_sum)}", cumulative, "ok" if e.success else "fail"))
    note = "" if len(results.episodes) <= MAX_CURVES else \
        f'<p class="muted">The first {MAX_CURVES} of {len(results.episodes)} episodes are drawn.</p>'
    legend = ('<p class="muted">Cumulative reward over the steps of each episode: <span class="yes">green</span> '
              'succeeded, <span class="no">red</span> did not.</p>')
    return legend + line_chart(series, x_label="step", y_label="cumulative reward", label="reward curves",
                               width=width, x_include=scales.steps, y_include=scales.cumulative) + note


def _strips_section(results: EvaluationResults, width: int = 640, scales: _Scales | None = None) -> str:
    scales = scales or _Scales()
    good = [e for e in results.episodes if e.success and e.time_to_success_s is not None]
    parts = []
    if good:
        parts.append('<p class="muted">Time from reset to the first success (simulated seconds), one dot per '
                     "successful episode; the bar is the median.</p>")
        titles = [f"episode {e.episode}, seed {e.seed}: {_num(e.time_to_success_s)} s" for e in good]
        parts.append(strip_chart([Series("success", [e.time_to_success_s or 0.0 for e in good], "ok")],
                                 x_label="time to success (s)", label="time to success", width=width,
                                 x_include=scales.times, value_labels=[titles]))
    else:
        parts.append('<p class="muted">No episode succeeded, so there is no time to success to show.</p>')
    ok = [e for e in results.episodes if e.success]
    bad = [e for e in results.episodes if not e.success]
    rows = [(Series("success", [e.reward_sum for e in ok], "ok"), ok),
            (Series("failure", [e.reward_sum for e in bad], "fail"), bad)]
    rows = [(s, eps) for s, eps in rows if eps]
    if rows:
        parts.append('<p class="muted">Reward sum per episode, by outcome.</p>')
        labels = [[f"episode {e.episode}, seed {e.seed}: {_num(e.reward_sum)}" for e in eps] for _, eps in rows]
        parts.append(strip_chart([s for s, _ in rows], x_label="reward sum", label="reward sums", width=width,
                                 x_include=scales.reward_sums, value_labels=labels))
    return "".join(parts)


def _image_uri(results: EvaluationResults, relative: str) -> str | None:
    """A ``data:`` URI of a JPEG or PNG frame inside the output directory, or None (missing, too big, not an image)."""
    path = results.frame_file(relative)
    if path is None:
        return None
    try:
        data = read_capped(path, results.limits.max_frame_bytes)
    except (OSError, ResultsError):
        return None
    if data.startswith(b"\xff\xd8\xff"):
        kind = "jpeg"
    elif data.startswith(b"\x89PNG\r\n\x1a\n"):
        kind = "png"
    else:
        return None
    return f"data:image/{kind};base64,{base64.b64encode(data).decode('ascii')}"


def _filmstrip(results: EvaluationResults, episode: EpisodeResult, title: str) -> str:
    figures = []
    frames = episode.frames[:MAX_FILMSTRIP_FRAMES]
    for i, relative in enumerate(frames):
        uri = _image_uri(results, relative)
        caption = f"{i + 1}/{len(frames)}"
        if uri is None:
            figures.append(f'<figure><div class="missing" title="{_e(relative)}">frame missing</div>'
                           f"<figcaption>{_e(caption)}</figcaption></figure>")
        else:
            figures.append(f'<figure><img alt="frame {i + 1} of episode {episode.episode}" src="{uri}">'
                           f"<figcaption>{_e(caption)}</figcaption></figure>")
    more = "" if len(episode.frames) <= MAX_FILMSTRIP_FRAMES else \
        f'<p class="muted">{len(episode.frames) - MAX_FILMSTRIP_FRAMES} more frames not shown.</p>'
    head = (f"<h3>{_e(title)}: episode {episode.episode}, seed {episode.seed}, ended {_e(episode.ended)} after "
            f"{episode.steps} steps</h3>")
    if not figures:
        return head + '<p class="muted">This episode has no frames.</p>'
    return f'{head}<div class="film">{"".join(figures)}</div>{more}'


def _filmstrip_section(results: EvaluationResults) -> str:
    def pick(success: bool) -> EpisodeResult | None:
        matching = [e for e in results.episodes if e.success == success]
        with_frames = [e for e in matching if e.frames]
        chosen = with_frames or matching
        return chosen[0] if chosen else None

    parts = []
    for success, title in ((False, "A failed episode"), (True, "A successful episode")):
        episode = pick(success)
        if episode is None:
            parts.append(f'<p class="muted">No {"successful" if success else "failed"} episode.</p>')
        else:
            parts.append(_filmstrip(results, episode, title))
    return "".join(parts)


def _episode_rows(results: EvaluationResults) -> str:
    rows = []
    for e in results.episodes[:MAX_EPISODES_SHOWN]:
        reason = e.reason or ""
        if len(reason) > MAX_REASON_CHARS:
            reason = reason[:MAX_REASON_CHARS] + "…"
        success = _yes_no(e.success)
        tts = _DASH if e.time_to_success_s is None else _num(e.time_to_success_s)
        rows.append([f'<td class="num">{e.episode}</td>', f'<td class="num" data-field="seed">{e.seed}</td>',
                     f'<td data-field="success">{success}</td>',
                     f'<td class="num" data-field="reward_sum">{_e(_num(e.reward_sum))}</td>',
                     f'<td class="num" data-field="steps">{e.steps}</td>',
                     f'<td class="num" data-field="time_to_success_s">{_e(tts)}</td>',
                     f'<td data-field="ended">{_e(e.ended)}</td>', f'<td data-field="reason">{_e(reason)}</td>'])
    table = _table(["episode", "seed", "success", "reward sum", "steps", "time to success (s)", "ended", "reason"],
                   rows, "episodes")
    note = "" if results.n <= MAX_EPISODES_SHOWN else \
        f'<p class="muted">The first {MAX_EPISODES_SHOWN} of {results.n} episodes; results.jsonl has them all.</p>'
    return table + note


def render_report(results: EvaluationResults) -> str:
    """The report page of ``results`` as an HTML string."""
    name = results.info.name
    rate = interval_chart([(name, results.success_rate, *wilson_interval(results.successes, results.n), "ok")],
                          label="success rate")
    body = (f"<h1>Evaluation: {_e(name)}</h1>{_info_section(results)}"
            f'<div class="two"><section><h2>Success rate</h2>{_headline(results)}{rate}</section>'
            f"<section><h2>Figures</h2>{_figures_section(results)}</section></div>"
            f'<div class="two"><section><h2>Reward curves</h2>{_curves_section(results)}</section>'
            f"<section><h2>Time to success and reward sums</h2>{_strips_section(results)}</section></div>"
            f"<h2>Filmstrip</h2>{_filmstrip_section(results)}"
            f"<h2>Episodes</h2>{_episode_rows(results)}")
    return _page(f"Evaluation: {name}", body)


def _write(path: Path, text: str) -> Path:
    """Write ``text`` to ``path`` through a temporary file, so a reader never sees half a page."""
    path.parent.mkdir(parents=True, exist_ok=True)
    temporary = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    temporary.write_text(text, encoding="utf-8")
    os.replace(temporary, path)
    return path


def write_report(out_dir: str | Path, *, results: EvaluationResults | None = None,
                 path: str | Path | None = None) -> Path:
    """Write the report of the evaluation in ``out_dir`` to ``out_dir/report.html`` (or ``path``); its path.

    Works on partial results too (an interrupted run): the page says the run did not finish.
    """
    loaded = results if results is not None else load_results(out_dir)
    target = Path(path) if path is not None else Path(out_dir) / REPORT_FILE
    return _write(target, render_report(loaded))


def _verdict_html(comparison: Comparison) -> str:
    css = {"worse": "worse", "better": "better"}.get(comparison.verdict, "same")
    return (f'<p class="verdict {css}" id="verdict" data-verdict="{_e(comparison.verdict)}">B is '
            f"{_e(comparison.verdict_text())}</p>"
            f'<p>Difference {comparison.difference * 100:+.1f} points; two-sided Fisher exact test '
            f'<span id="p-value" data-p="{comparison.p_value!r}">p = {comparison.p_value:.4g}</span> at '
            f"alpha {comparison.alpha:g}.</p>")


def _flipped_section(comparison: Comparison) -> str:
    if not comparison.flipped:
        return '<p class="muted">No seed that both runs ran changed its outcome.</p>'
    rows = [[f'<td class="num">{seed}</td>', f"<td>{_yes_no(a)}</td>", f"<td>{_yes_no(b)}</td>"]
            for seed, a, b in comparison.flipped[:MAX_EPISODES_SHOWN]]
    return _table(["seed", "A succeeded", "B succeeded"], rows, "flipped")


def render_comparison(comparison: Comparison, a: EvaluationResults, b: EvaluationResults) -> str:
    """The comparison page of runs ``a`` and ``b`` as an HTML string."""
    sa, sb = comparison.a, comparison.b
    chart = interval_chart([(f"A {sa.name}", sa.rate, sa.low, sa.high, "a"),
                            (f"B {sb.name}", sb.rate, sb.low, sb.high, "b")], label="success rates")
    columns = []
    scales = _Scales.of(a, b)  # both runs' charts on the same scales, to be compared by eye
    for letter, results in (("A", a), ("B", b)):
        columns.append(f'<div class="run" id="run-{letter.lower()}"><h2>{letter}: {_e(results.info.name)}</h2>'
                       f"{_info_section(results)}{_headline(results)}{_figures_section(results)}"
                       f"<h3>Reward curves</h3>{_curves_section(results, 620, scales)}"
                       f"<h3>Time to success and reward sums</h3>{_strips_section(results, 620, scales)}</div>")
    seeds_note = "" if comparison.same_seeds else \
        '<p class="note">The two runs did not use the same seeds: part of the difference may be the draw.</p>'
    body = (f"<h1>Comparison: A {_e(sa.name)} vs B {_e(sb.name)}</h1>{_verdict_html(comparison)}{seeds_note}"
            f"{chart}<div class=\"side\">{''.join(columns)}</div>"
            f"<h2>Seeds whose outcome changed</h2>{_flipped_section(comparison)}")
    return _page(f"Comparison: {sa.name} vs {sb.name}", body)


def write_comparison_report(dir_a: str | Path | EvaluationResults, dir_b: str | Path | EvaluationResults,
                            out: str | Path, *, alpha: float = 0.05) -> Path:
    """Write the comparison of evaluation B (candidate) with A (reference) to the HTML file ``out``; its path.

    ``dir_a`` / ``dir_b`` are output directories, or results already loaded.
    """
    a = dir_a if isinstance(dir_a, EvaluationResults) else load_results(dir_a)
    b = dir_b if isinstance(dir_b, EvaluationResults) else load_results(dir_b)
    comparison = compare_runs(a, b, alpha=alpha)
    return _write(Path(out), render_comparison(comparison, a, b))

