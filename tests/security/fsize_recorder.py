"""A recorder hitting a file size limit (RLIMIT_FSIZE: EFBIG, deterministic) that is lifted later.

Run as ``python -m tests.security.fsize_recorder OUT.mcap``: records ``n`` (Int64) values from the
memory transport, lowers this process's file size limit to ``LIMIT_BYTES`` after ``BEFORE``
values, publishes ``DURING`` more, lifts the limit, publishes ``AFTER`` more and stops. Prints
one JSON line: the recorder's statistics and how many warnings the recording logger wrote.
"""

from __future__ import annotations

import json
import logging
import resource
import sys
import time

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


def main(path: str) -> None:
    counter = _Count()
    logging.getLogger("agents_core").addHandler(counter)
    soft, hard = resource.getrlimit(resource.RLIMIT_FSIZE)
    topic = Topic("n", "Int64")
    with MemoryTransport() as transport:
        recorder = Recorder(transport, path, topics=[topic], include_status=False, encoding="msgpack",
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
        resource.setrlimit(resource.RLIMIT_FSIZE, (LIMIT_BYTES, hard))
        send(DURING)
        time.sleep(0.3)
        resource.setrlimit(resource.RLIMIT_FSIZE, (soft, hard))
        time.sleep(1.2)  # past the writer's retry interval
        send(AFTER)
        time.sleep(0.3)
        stats = recorder.stop()
    print(json.dumps({"sent": sent, "received": stats.received, "written": stats.written,
                      "lost": getattr(stats, "lost", None), "errors": stats.errors, "dropped": stats.dropped,
                      "write_failures": getattr(stats, "write_failures", None),
                      "files": [str(f) for f in stats.files], "warnings": counter.count,
                      "warning_lines": counter.lines}))


if __name__ == "__main__":
    main(sys.argv[1])
