"""An action server process for the goal tests: ``python -m tests.agents_zenoh.goal_server PORT NAME``.

Serves VisionLanguageAction goals that run until cancelled (feedback every 20 ms) on a Zenoh peer
listening on ``tcp/127.0.0.1:PORT``; prints READY, then serves until killed.
"""

from __future__ import annotations

import sys
import threading
from typing import Any

from agents_core.transport.goals import GoalHandle
from agents_zenoh.transport import ZenohTransport


def execute(handle: GoalHandle) -> dict[str, Any]:
    step = 0
    while not handle.wait_for_cancel(0.02):
        step += 1
        handle.publish_feedback({"step": step})
    return {"success": False, "steps": step}


def main() -> int:
    port, name = int(sys.argv[1]), sys.argv[2]
    transport = ZenohTransport(mode="peer", listen=[f"tcp/127.0.0.1:{port}"], connect=[], multicast_scouting=False)
    transport.create_action_server(name, "VisionLanguageAction", execute)
    print("READY", flush=True)
    threading.Event().wait(120.0)  # bounded: the test kills it long before
    transport.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
