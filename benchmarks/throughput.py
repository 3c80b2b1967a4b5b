"""Throughput through the relay: messages/s and MB/s with a bounded number of messages in flight.

The pinger keeps at most ``window`` messages in flight (a new one is sent as each echo returns),
for ``seconds`` or ``max_messages``, whichever comes first. The window (8) is below the
framework's default queue depths (10 per subscription and per component worker), so neither side
drops anything and the figure is the sustained rate, not how fast messages can be thrown away.
A warm-up pump, not counted, runs first. MB/s counts the payload once per message (64 B or
921,600 B), the size that crosses the relay in each direction.
"""

from __future__ import annotations

import threading
import time
from typing import Any

from .channels import Channel
from .common import PAYLOADS

#: Messages in flight at most.
WINDOW = 8
#: No echo for this long ends a pump early (it is reported as stalled).
STALL_TIMEOUT = 5.0


class _Counter:
    """Counts echoes with sequence numbers of the current pump and hands back credit."""

    def __init__(self, window: int) -> None:
        self.credit = threading.Semaphore(window)
        self._lock = threading.Lock()
        self.base = 0
        self.received = 0
        self.last_ns = 0
        self.done = threading.Event()
        self.expected = -1

    def start(self, base: int, window: int) -> None:
        with self._lock:
            self.base, self.received, self.last_ns, self.expected = base, 0, 0, -1
            self.credit = threading.Semaphore(window)
            self.done.clear()

    def expect(self, total: int) -> None:
        with self._lock:
            self.expected = total
            if self.received >= total:
                self.done.set()

    def __call__(self, seq: int) -> None:
        now = time.perf_counter_ns()
        with self._lock:
            if seq < self.base:
                return  # a late echo of an earlier pump: neither counted nor credited
            self.received += 1
            self.last_ns = now
            if self.received == self.expected:
                self.done.set()
            credit = self.credit
        credit.release()


def _pump(channel: Channel, counter: _Counter, base: int, window: int, seconds: float,
          max_messages: int) -> dict[str, Any]:
    counter.start(base, window)
    start_ns = time.perf_counter_ns()
    deadline = time.monotonic() + seconds
    sent = 0
    stalled = False
    while sent < max_messages and time.monotonic() < deadline:
        if not counter.credit.acquire(timeout=STALL_TIMEOUT):
            stalled = True
            break
        channel.send(base + sent)
        sent += 1
    counter.expect(sent)
    counter.done.wait(STALL_TIMEOUT)
    elapsed = max(counter.last_ns - start_ns, 1) / 1e9
    return {"sent": sent, "received": counter.received, "seconds": elapsed, "stalled": stalled}


def measure_throughput(channel: Channel, *, seconds: float, max_messages: int, warmup_seconds: float,
                       base_seq: int, window: int = WINDOW) -> dict[str, Any]:
    """Warm up, then pump for ``seconds`` (at most ``max_messages``); rates of the counted pump."""
    counter = _Counter(window)
    channel.on_reply = counter
    _pump(channel, counter, base_seq, window, warmup_seconds, max_messages)
    result = _pump(channel, counter, base_seq + max_messages + window, window, seconds, max_messages)
    rate = result["received"] / result["seconds"] if result["received"] else 0.0
    result.update(window=window, msgs_per_s=rate, mb_per_s=rate * PAYLOADS[channel.payload] / 1e6,
                  lost=result["sent"] - result["received"])
    return result
