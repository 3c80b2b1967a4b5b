"""EpisodeProgress: one line per episode in a log, one redrawn bar on a real terminal (a pty)."""

from __future__ import annotations

import fcntl
import io
import os
import pty
import re
import struct
import termios
import threading

import pytest

from agents_core.evals.progress import EpisodeProgress, format_duration


class _Clock:
    def __init__(self) -> None:
        self.now = 1000.0

    def __call__(self) -> float:
        return self.now


def test_a_log_gets_one_line_per_episode_with_successes_rate_and_time_left() -> None:
    stream, clock = io.StringIO(), _Clock()
    progress = EpisodeProgress(4, stream, clock=clock)
    assert stream.getvalue() == ""  # nothing is drawn before the first episode in a log
    for success in (True, False, True):
        clock.now += 10.0
        progress.episode_done(success, wall_s=9.5)
    clock.now += 10.0
    progress.close()
    lines = stream.getvalue().splitlines()
    assert lines == ["episode 1/4: success  (1/1 succeeded, 100 %)  0:30 left",
                     "episode 2/4: failure  (1/2 succeeded, 50 %)  0:20 left",
                     "episode 3/4: success  (2/3 succeeded, 67 %)  0:10 left",
                     "3/4 episodes in 0:40: 2 succeeded (67 %) (stopped: 1 not run)"]
    assert "\r" not in stream.getvalue() and "\x1b" not in stream.getvalue()
    progress.episode_done(True, 1.0)
    progress.close()
    assert stream.getvalue().splitlines() == lines  # nothing after close


def test_parallel_episodes_count_at_the_rate_they_finish() -> None:
    stream, clock = io.StringIO(), _Clock()
    progress = EpisodeProgress(10, stream, clock=clock)
    clock.now += 6.0
    for _ in range(4):  # four episodes of 6 s each, run side by side, end together
        progress.episode_done(True, wall_s=6.0)
    assert progress.seconds_left() == pytest.approx(6.0 / 4 * 6)
    assert (progress.done, progress.successes, progress.rate) == (4, 4, 1.0)


def test_calls_from_many_threads_are_all_counted() -> None:
    stream = io.StringIO()
    progress = EpisodeProgress(200, stream)
    start = threading.Barrier(8)

    def worker(k: int) -> None:
        start.wait(timeout=10)
        for i in range(25):
            progress.episode_done((i + k) % 2 == 0, 0.01)

    threads = [threading.Thread(target=worker, args=(k,)) for k in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout=30)
    progress.close()
    lines = stream.getvalue().splitlines()
    assert progress.done == 200 and progress.successes == 100 and len(lines) == 201
    assert lines[-1].startswith("200/200 episodes in ") and "(stopped" not in lines[-1]
    # Each line is whole (no two writes interleaved) and the counts climb one by one.
    assert [int(re.match(r"episode (\d+)/200", line).group(1)) for line in lines[:-1]] == list(range(1, 201))  # type: ignore[union-attr]


def _read_all(fd: int) -> bytes:
    chunks = []
    while True:
        try:
            chunk = os.read(fd, 65536)
        except OSError:  # EIO: the other end is closed and drained
            break
        if not chunk:
            break
        chunks.append(chunk)
    return b"".join(chunks)


def test_a_terminal_gets_one_bar_redrawn_in_place_never_wider_than_the_terminal() -> None:
    master, slave = pty.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 60, 0, 0))  # 60 columns
    # The terminal must not turn our "\n" into "\r\n" behind our back: read exactly what was written.
    attrs = termios.tcgetattr(slave)
    attrs[1] &= ~termios.OPOST
    termios.tcsetattr(slave, termios.TCSANOW, attrs)
    stream = os.fdopen(slave, "w", encoding="utf-8")
    clock = _Clock()
    try:
        progress = EpisodeProgress(20, stream, clock=clock)
        assert progress.tty
        for i in range(20):
            clock.now += 2.0
            progress.episode_done(i % 4 != 0, 1.9)
        progress.close()
    finally:
        stream.close()
    output = _read_all(master).decode("utf-8")
    os.close(master)
    bar, summary = output.rstrip("\n").split("\n")
    draws = bar.split("\r")[1:]
    assert len(draws) == 1 + 20 + 1  # at the start, after each episode, and the final state
    for draw in draws:
        assert draw.endswith("\x1b[K") and len(draw) - len("\x1b[K") <= 59
    assert draws[0].startswith("episodes 0/20 [--------------------]  success 0/0 (0 %)")
    assert draws[10].startswith("episodes 10/20 [##########----------]  success 7/10 (70 %)")
    assert draws[-1].startswith("episodes 20/20 [####################]  success 15/20 (75 %)")
    assert summary == "20/20 episodes in 0:40: 15 succeeded (75 %)"


def test_a_closed_stream_does_not_end_the_evaluation() -> None:
    stream = io.StringIO()
    progress = EpisodeProgress(2, stream)
    stream.close()
    progress.episode_done(True, 0.1)
    progress.close()
    assert progress.done == 1


def test_durations_and_bad_totals() -> None:
    assert [format_duration(s) for s in (0, 59.4, 61, 3600, 3725, float("nan"), float("inf"), -1)] == \
        ["0:00", "0:59", "1:01", "1:00:00", "1:02:05", "?", "?", "?"]
    for bad in (-1, 2.0, True, None):
        with pytest.raises(ValueError, match="total"):
            EpisodeProgress(bad, io.StringIO())  # type: ignore[arg-type]
