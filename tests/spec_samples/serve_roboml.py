"""Run the RoboML double (tests/servers/roboml_server.py) in its own process, to be killed mid-run.

Prints ``port <http/ws port>`` once listening, then serves until killed or ``max_seconds`` pass.
"""

from __future__ import annotations

import sys
import time

from tests.servers.roboml_server import RoboMLTestServer


def main() -> None:
    max_seconds = float(sys.argv[1]) if len(sys.argv) > 1 else 300.0
    with RoboMLTestServer() as server:
        print(f"port {server.port}", flush=True)
        deadline = time.monotonic() + max_seconds
        while time.monotonic() < deadline:
            time.sleep(0.2)


if __name__ == "__main__":
    main()
