"""Small real components used by several runtime tests (and copyable into users' own tests)."""

from __future__ import annotations

import threading
import time
from typing import Any

from agents_core.components import Component
from agents_core.ros import String


class Relay(Component):
    """Publishes each input string, transformed, on its first output; records what it saw."""

    def __init__(self, *, transform: Any = str.upper, step_seconds: float = 0.0, **kwargs: Any) -> None:
        self.allowed_inputs = {"Required": [String]}
        self.allowed_outputs = {"Optional": [String]}
        self.transform = transform
        self.step_seconds = step_seconds
        self.seen: list[Any] = []
        self.step_kwargs: list[dict[str, Any]] = []
        self._running = 0
        self.max_concurrent = 0
        self._guard = threading.Lock()
        self.step_threads: set[str] = set()
        super().__init__(**kwargs)

    def _execution_step(self, **kwargs: Any) -> None:
        with self._guard:
            self._running += 1
            self.max_concurrent = max(self.max_concurrent, self._running)
        try:
            self.step_threads.add(threading.current_thread().name)
            self.step_kwargs.append(kwargs)
            cbs = {**self.callbacks, **self.trig_callbacks}
            topic = kwargs.get("topic")
            value = cbs[topic.name].get_output() if topic is not None else next(iter(cbs.values())).get_output()
            self.seen.append(value)
            if self.step_seconds:
                time.sleep(self.step_seconds)
            if value is not None:
                for pub in self.publishers_dict.values():
                    pub.publish(self.transform(value))
        finally:
            with self._guard:
                self._running -= 1
