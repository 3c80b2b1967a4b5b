"""A recorder whose writes fail for a while: a file size limit, or a disk that fills up and is freed again.

``python -m tests.security.fsize_recorder OUT.mcap`` records ``n`` (Int64) values from the memory
transport, lowers this process's file size limit to ``LIMIT_BYTES`` after ``BEFORE`` values (EFBIG,
deterministic), publishes ``DURING`` more, lifts the limit, publishes ``AFTER`` more and stops.

``python -m tests.security.fsize_recorder --enospc DISK OUT.mcap`` records into ``DISK`` (a small
file system of its own: the test mounts a tmpfs there in a private mount namespace), and instead of
the limit fills ``DISK`` with a filler file until a write gets ENOSPC, then deletes it (space returns).
The recording's files are copied next to ``OUT.mcap`` before the process ends (the tmpfs goes with it).

Prints one JSON line: the recorder's statistics, how many warnings the recording logger wrote and
the files to read back.
"""

from __future__ import annotations

import argparse
import contextlib
import errno
import json
import logging
import os
import resource
import shutil
import time
from collections.abc import Callable
from pathlib import Path

from agents_core.recording import Recorder
from agents_core.topics import Topic
from agents_core.transport.memory import MemoryTransport

LIMIT_BYTES = 48 * 1024
BEFORE, DURING, AFTER = 300, 1500, 300


class _Count(logging.Handler):
    def __init__(self) -> None:
        super().__init__(logging.WARNING)
        self.count = 0
        self.lines: list[str] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.count += 1
        self.lines.append(record.getMessage()[:300])


def _fill(disk: Path) -> Path:
    """Write a filler file into ``disk`` until the file system says ENOSPC; the filler's path."""
    filler = disk / "filler"
    fd = os.open(filler, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    try:
        block = b"\0" * 4096
        for _ in range(1_000_000):  # bounded: a 4 GB disk at most
            try:
                os.write(fd, block)
            except OSError as exc:
                if exc.errno != errno.ENOSPC:
                    raise
                break
        else:
            raise RuntimeError(f"{disk} never filled up: is it a small file system of its own?")
    finally:
        os.close(fd)
    return filler


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--enospc", metavar="DISK", default=None)
    parser.add_argument("out")
    args = parser.parse_args()
    out = Path(args.out)
    counter = _Count()
    logging.getLogger("agents_core").addHandler(counter)
    soft, hard = resource.getrlimit(resource.RLIMIT_FSIZE)
    fail: Callable[[], None]
    recover: Callable[[], None]
    if args.enospc is None:
        path = out
        fail = lambda: resource.setrlimit(resource.RLIMIT_FSIZE, (LIMIT_BYTES, hard))  # noqa: E731
        recover = lambda: resource.setrlimit(resource.RLIMIT_FSIZE, (soft, hard))  # noqa: E731
    else:
        disk = Path(args.enospc)
        path = disk / out.name
        fillers: list[Path] = []
        fail = lambda: fillers.append(_fill(disk))  # noqa: E731
        recover = lambda: fillers.pop().unlink()  # noqa: E731
    topic = Topic("n", "Int64")
    with MemoryTransport() as transport:
        recorder = Recorder(transport, str(path), topics=[topic], include_status=False, encoding="msgpack",
                            flush_interval_s=0.05, chunk_size=4096, compression="none").start()
        publisher = transport.create_publisher(topic)
        sent = 0

        def send(n: int) -> None:
            nonlocal sent
            for _ in range(n):
                publisher.publish(sent)
                sent += 1
                time.sleep(0.001)

        send(BEFORE)
        time.sleep(0.3)
        fail()
        send(DURING)
        time.sleep(0.3)
        recover()
        time.sleep(1.2)  # past the writer's retry interval
        send(AFTER)
        time.sleep(0.3)
        stats = recorder.stop()
    files = [Path(f) for f in stats.files]
    if args.enospc is not None:  # copied out of the tmpfs, which ends with this process's namespace
        copies = []
        for f in files:
            with contextlib.suppress(FileNotFoundError):
                shutil.copyfile(f, out.with_name(f.name))
                copies.append(out.with_name(f.name))
        files = copies
    print(json.dumps({"sent": sent, "received": stats.received, "written": stats.written,
                      "lost": getattr(stats, "lost", None), "errors": stats.errors, "dropped": stats.dropped,
                      "write_failures": getattr(stats, "write_failures", None),
                      "files": [str(f) for f in files], "warnings": counter.count,
                      "warning_lines": counter.lines}))


if __name__ == "__main__":
    main()
