"""The rmw_zenoh suite: the hop and throughput of ``benchmarks.hop`` on the rmw_zenoh transport.

Framework: an ``EchoRelay`` under ``Launcher(transport="rmw_zenoh")`` (its process also hosts the Zenoh router the
two sides meet through, as rmw_zenoh needs one) and a pinger on an rmw_zenoh transport: CDR payloads, rmw_zenoh
keys, attachments and liveliness tokens. Raw: zenoh-python alone (``benchmarks.hop``'s raw Zenoh relay and pinger,
bytes in and out). Records carry ``transport="rmw_zenoh"``; the report's ratio is rmw_zenoh ÷ raw zenoh-python, and
the hop suite's ros2 framework figures of the same run give rmw_zenoh ÷ the ros2 transport.

And the goal round trip of ``benchmarks.goals`` (a goal with N feedbacks, sent to its result): ``send_goal`` /
``create_action_server`` as a ROS 2 action in rmw_zenoh's format between two rmw_zenoh peers of a router, ÷ raw
zenoh-python's queryable doing the same exchange between two plain peers of a router (records ``suite="goals"``,
``transport="rmw_zenoh"``).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from . import goals, hop
from .common import Children, available

__all__ = ["run_suite"]


def unavailable() -> str | None:
    """Why the suite cannot run here, or None."""
    for module in ("zenoh", "rosbags", "xxhash", "agents_interfaces"):
        if not available(module):
            return f"{module} is not installed (pip install -e '.[rmw-zenoh]' and ./interfaces)"
    return None


def run_suite(settings: dict[str, Any], children: Children, ros_domain: int,
              progress: Callable[[str], None]) -> tuple[list[dict[str, Any]], list[dict[str, str]]]:
    """Raw zenoh and framework rmw_zenoh hop pairs, alternating which goes first each round, then the goal round
    trip (raw, then framework, in one child); (records, skipped)."""
    reason = unavailable()
    if reason is not None:
        progress(f"rmw_zenoh: skipped: {reason}")
        return [], [{"suite": "rmw_zenoh", "transport": "rmw_zenoh", "mode": "both", "reason": reason}]
    records: list[dict[str, Any]] = []
    skipped: list[dict[str, str]] = []
    for round_no in range(int(settings.get("rounds", 1))):
        for mode in ("raw", "framework") if round_no % 2 == 0 else ("framework", "raw"):
            got: list[dict[str, Any]] = []
            failure = hop._run_pair("zenoh" if mode == "raw" else "rmw_zenoh", mode, round_no, settings, children,
                                    ros_domain, progress, got)
            for record in got:
                record["transport"] = "rmw_zenoh"
            records += got
            if failure is not None:
                progress(f"rmw_zenoh {mode}: FAILED: {failure.splitlines()[0]}")
                skipped.append({"suite": "rmw_zenoh", "transport": "rmw_zenoh", "mode": mode,
                                "reason": failure[-1500:]})
    goal_records, goal_skipped = goals.run_suite(["rmw_zenoh"], settings, children, ros_domain, progress)
    return records + goal_records, skipped + goal_skipped
