"""This process's CPU time and resident memory, read from the OS (no third-party package)."""

from __future__ import annotations

import os
import resource
import time

from attrs import define

__all__ = ["CpuMeter", "ProcessFigures", "process_figures"]

_PAGE = os.sysconf("SC_PAGE_SIZE") if hasattr(os, "sysconf") else 4096


@define(frozen=True)
class ProcessFigures:
    """CPU seconds used so far (user + system) and the resident set size in bytes."""

    cpu_seconds: float
    rss_bytes: int


def process_figures() -> ProcessFigures:
    """The figures of this process now (RSS from ``/proc/self/statm``, else the peak from ``getrusage``)."""
    usage = resource.getrusage(resource.RUSAGE_SELF)
    rss = 0
    try:
        with open("/proc/self/statm", "rb") as statm:
            rss = int(statm.read().split()[1]) * _PAGE
    except (OSError, ValueError, IndexError):
        rss = usage.ru_maxrss * 1024  # Linux reports KiB; the peak, not the current size
    return ProcessFigures(usage.ru_utime + usage.ru_stime, rss)


class CpuMeter:
    """The CPU share (1.0 = one core) of this process between two readings."""

    def __init__(self) -> None:
        self._last = (time.monotonic(), process_figures().cpu_seconds)

    def share(self, figures: ProcessFigures) -> float:
        """The share since the previous call (or since construction)."""
        now = time.monotonic()
        then, cpu = self._last
        self._last = (now, figures.cpu_seconds)
        elapsed = now - then
        return 0.0 if elapsed <= 0 else max(0.0, (figures.cpu_seconds - cpu) / elapsed)
