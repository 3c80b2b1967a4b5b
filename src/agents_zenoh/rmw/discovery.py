"""The ROS 2 graph from rmw_zenoh's liveliness tokens: topics with their counts, and the lifecycle nodes."""

from __future__ import annotations

import logging
import time
from typing import Any

import zenoh

from agents_core.transport.graph import Graph, TopicInfo

from .wire import TokenError, parse_token

__all__ = ["core_type_names", "discover_graph"]

logger = logging.getLogger(__name__)


def core_type_names() -> dict[str, str]:
    """``pkg::msg::dds_::Type_`` -> the core's type name, for every registered conversion."""
    from agents_ros2.conversions import registered_conversions  # noqa: PLC0415

    from .typesupport import ros_type_name  # noqa: PLC0415
    from .wire import dds_type_name  # noqa: PLC0415

    names: dict[str, str] = {}
    for name, conversion in registered_conversions().items():
        try:
            names.setdefault(dds_type_name(ros_type_name(conversion.ros_type)), name)
        except Exception:  # noqa: BLE001, S112  # a conversion without a ROS type name
            continue
    return names


def _tokens(session: zenoh.Session, domain_id: int, timeout: float) -> set[str]:
    """Every live token of the domain. Two gets, 50 ms apart: a get right after another one may be answered by
    nobody (seen with zenoh-python 1.10 through a router), and a token missing from both is not live."""
    found: set[str] = set()
    deadline = time.monotonic() + timeout
    for attempt in range(2):
        if attempt:
            time.sleep(0.05)
        remaining = max(0.05, deadline - time.monotonic())
        replies: Any = session.liveliness().get(f"@ros2_lv/{domain_id}/**", timeout=remaining)
        found.update(str(reply.ok.key_expr) for reply in replies if reply.ok is not None)
    return found


def discover_graph(session: zenoh.Session, domain_id: int, timeout: float) -> Graph:
    """Every token under ``@ros2_lv/<domain>/**`` as a :class:`Graph` (bogus tokens are skipped, logged)."""
    counts: dict[tuple[str, str], list[int]] = {}
    services: set[str] = set()
    names = core_type_names()
    for key in _tokens(session, domain_id, timeout):
        try:
            token = parse_token(key)
        except TokenError as exc:
            logger.debug("skipped a liveliness token: %s", exc)
            continue
        if token.kind in ("MP", "MS"):
            msg_type = names.get(token.ros_type, token.ros_type.replace("::dds_::", "::").replace("::", "/")
                                 .rstrip("_"))
            entry = counts.setdefault((token.name.lstrip("/"), msg_type), [0, 0])
            entry[0 if token.kind == "MP" else 1] += 1
        elif token.kind == "SS" and token.name.endswith("/change_state"):
            services.add(token.name.lstrip("/").removesuffix("/change_state"))
    topics = [TopicInfo(name=n, msg_type=t, publishers=p, subscribers=s) for (n, t), (p, s) in counts.items()]
    return Graph(topics=topics, components=sorted(services))
