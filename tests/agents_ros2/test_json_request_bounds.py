"""ROS 2 JsonCall bodies come from the network: decoded under the request limits, as on Zenoh.

A plain rclpy client (a node of the other transport, sending JsonCall requests it builds itself)
sends the hostile shapes of ``tests/agents_zenoh/test_request_decode_bounds.py`` that JSON can
express; each is answered ``success=False`` with the limit named, and a normal request is answered
right after. A server whose reply does not decode gives the caller a RemoteError, not a traceback
from ``json``.
"""

from __future__ import annotations

import json
import os
import time
from collections.abc import Iterator
from typing import Any

import pytest

pytest.importorskip("rclpy", reason="needs the ros2 extra")
pytest.importorskip("agents_interfaces", reason="needs agents_interfaces (pip install --no-build-isolation "
                                                "./interfaces)")

from agents_interfaces.srv import JsonCall

from agents_core.errors import RemoteError
from agents_ros2.transport import Ros2Transport
from tests.conformance.ros2_pair import ros2_pair
from tests.conftest import wait_for

pytestmark = pytest.mark.ros2

SUFFIX = f"_{os.getpid()}"
_MIB = 1024 * 1024

HOSTILE = {
    "many small objects (8 MB of {})": ("[" + ",".join(["{}"] * (8 * _MIB // 3)) + "]", "max_objects"),
    "deep nesting (100k brackets)": ("[" * 100_000 + "]" * 100_000, "max_depth"),
    "huge int (10**400)": (json.dumps({"x": 10**400}), "max_int"),
    "NaN": ('{"x": NaN}', "allow_non_finite"),
    "wrong top-level type": ("[1, 2]", "a request must be a JSON object"),
    "truncated": ('{"x": "ab', "never closed"),
}


@pytest.fixture(scope="module")
def served() -> Iterator[tuple[Ros2Transport, Ros2Transport, Any]]:
    with ros2_pair() as (a, b):
        assert isinstance(a, Ros2Transport) and isinstance(b, Ros2Transport)
        a.create_service("echo_x" + SUFFIX, lambda req: {"echo": req.get("x")})
        client = b.driver.node.create_client(JsonCall, "/echo_x" + SUFFIX)
        assert wait_for(client.service_is_ready, timeout=20.0), "the service never appeared"
        yield a, b, client


def _call(client: Any, request_json: str) -> tuple[float, Any]:
    start = time.monotonic()
    future = client.call_async(JsonCall.Request(request_json=request_json))
    assert wait_for(future.done, timeout=30.0, interval=0.01), "no reply"
    return time.monotonic() - start, future.result()


@pytest.mark.parametrize("shape", list(HOSTILE))
def test_a_hostile_json_call_is_refused_naming_the_limit_and_the_next_one_is_answered(
        served: tuple[Ros2Transport, Ros2Transport, Any], shape: str) -> None:
    _, _, client = served
    document, named = HOSTILE[shape]
    elapsed, response = _call(client, document)
    assert not response.success, response.response_json[:200]
    assert named in response.error, response.error
    assert response.error.split(":")[0] in ("JsonLimitError", "InvalidJsonError", "ConfigError"), response.error
    normal_elapsed, normal = _call(client, json.dumps({"x": 7}))
    assert normal.success and json.loads(normal.response_json) == {"echo": 7}
    print(f"\nROS 2 {shape}: refused in {elapsed:.3f} s ({response.error[:90]}); next call {normal_elapsed:.3f} s")


@pytest.mark.parametrize(("reply", "named"), [
    ("[" * 100_000 + "]" * 100_000, "max_depth"),
    ('{"x": NaN}', "allow_non_finite"),
    ("[1, 2]", "not a JSON object"),
])
def test_a_reply_that_does_not_decode_is_a_remote_error(
        served: tuple[Ros2Transport, Ros2Transport, Any], reply: str, named: str) -> None:
    a, b, _ = served
    name = f"hostile_reply_{abs(hash(reply)) % 10**6}{SUFFIX}"

    def answer(request: Any, response: Any) -> Any:
        response.success, response.response_json = True, reply
        return response

    service = a.driver.node.create_service(JsonCall, "/" + name, answer)
    try:
        with pytest.raises(RemoteError, match=named):
            b.request(name, {}, timeout=20.0)
    finally:
        a.driver.node.destroy_service(service)
