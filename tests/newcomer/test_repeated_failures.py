"""Item 8 of issue 38: a step that fails at every step is logged once, then counted (a summary line when it
recovers, or every SUMMARY_EVERY_S while it goes on), instead of the same line at every step."""

from __future__ import annotations

import logging
import time
from typing import Any

import pytest

from agents_core import Launcher
from agents_core.components import Component
from agents_core.testing.helpers import wait_for


class Flaky(Component):
    """Fails at every step until told not to."""

    def __init__(self, **kwargs: Any) -> None:
        self.failing = True
        self.steps = 0
        super().__init__(**kwargs)

    def _execution_step(self, **kwargs: Any) -> None:
        self.steps += 1
        if self.failing:
            raise RuntimeError("the sensor is unplugged")


def _lines(caplog: pytest.LogCaptureFixture, text: str) -> list[str]:
    return [r.getMessage() for r in caplog.records if text in r.getMessage()]


def test_a_failing_step_is_said_once_then_counted(caplog: pytest.LogCaptureFixture) -> None:
    flaky = Flaky(inputs=[], outputs=[], trigger=50.0, component_name="flaky")
    launcher = Launcher("memory")
    launcher.add_pkg(components=[flaky])
    with caplog.at_level(logging.INFO, logger="agents_core"), launcher:
        assert wait_for(lambda: flaky.steps >= 30, 10.0)
        failing_steps = flaky.steps
        flaky.failing = False
        assert wait_for(lambda: bool(_lines(caplog, "before recovering")), 5.0)
    said = _lines(caplog, "step failed (")
    assert said[0] == "step failed (COMPONENT_FAILURE): RuntimeError: the sensor is unplugged", said
    assert len(said) == 2, said  # the first, and the summary
    summary = said[1]
    counted = int(summary.rsplit("unplugged: ", 1)[1].split(" ")[0])
    assert counted >= failing_steps - 2 and "before recovering" in summary, (summary, failing_steps)


def test_a_failure_that_goes_on_is_summarised_periodically(caplog: pytest.LogCaptureFixture,
                                                           monkeypatch: pytest.MonkeyPatch) -> None:
    from agents_core.runtime import repeated_failures  # noqa: PLC0415

    monkeypatch.setattr(repeated_failures, "SUMMARY_EVERY_S", 0.5)
    flaky = Flaky(inputs=[], outputs=[], trigger=50.0, component_name="flaky2")
    launcher = Launcher("memory")
    launcher.add_pkg(components=[flaky])
    with caplog.at_level(logging.INFO, logger="agents_core"), launcher:
        time.sleep(1.6)
    summaries = _lines(caplog, "so far")
    assert 2 <= len(summaries) <= 4, summaries
    assert len(_lines(caplog, "step failed (")) <= 1 + len(summaries) + 1


def test_a_failure_that_lasts_until_the_stop_is_counted_at_the_stop(caplog: pytest.LogCaptureFixture) -> None:
    flaky = Flaky(inputs=[], outputs=[], trigger=50.0, component_name="flaky3")
    launcher = Launcher("memory")
    launcher.add_pkg(components=[flaky])
    with caplog.at_level(logging.INFO, logger="agents_core"), launcher:
        assert wait_for(lambda: flaky.steps >= 20, 10.0)
    said = _lines(caplog, "step failed (")
    assert len(said) == 2 and said[1].endswith("(before stopping)"), said
    counted = int(said[1].rsplit("unplugged: ", 1)[1].split(" ")[0])
    assert 19 <= counted <= flaky.steps - 1, (said, flaky.steps)
