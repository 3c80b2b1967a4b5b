"""The README's testing example, run as written (examples that no test runs will rot)."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

README = Path(__file__).resolve().parent.parent / "README.md"


def _python_blocks() -> list[str]:
    return re.findall(r"```python\n(.*?)```", README.read_text(), flags=re.S)


def test_readme_component_and_test_example_run() -> None:
    blocks = _python_blocks()
    component = next(b for b in blocks if "class Shout" in b)
    test = next(b for b in blocks if "def test_shout" in b)
    namespace: dict[str, Any] = {}
    exec(compile(component + "\n" + test, str(README), "exec"), namespace)
    namespace["test_shout"]()


def test_readme_own_message_type_runs_on_memory_and_where_installed_zenoh_and_ros2() -> None:
    from agents_core import supported_types  # noqa: PLC0415  # keep the README test's imports light
    from agents_core.errors import TypeValidationError  # noqa: PLC0415
    from agents_core.messages import values_equal  # noqa: PLC0415
    from agents_core.testing.helpers import wait_for  # noqa: PLC0415
    from agents_core.testing.pairs import memory_pair, missing_requirement, pair_factory  # noqa: PLC0415

    block = next(b for b in _python_blocks() if "class LabelMsg" in b)
    supported_types._registry.unregister("Label")  # the block registers it: allow running this test again
    namespace: dict[str, Any] = {}
    exec(compile(block, str(README), "exec"), namespace)
    topic, label_type = namespace["labels"], namespace["Label"]
    ran: list[str] = []
    for name in ("memory", "zenoh", "ros2"):
        if name != "memory" and (missing_requirement(name) or not _importable("agents_interfaces")):
            continue
        ran.append(name)
        with (memory_pair if name == "memory" else pair_factory(name))() as (a, b):
            received: list[Any] = []
            sub = b.create_subscription(topic, received.append)
            pub = a.create_publisher(topic)
            assert wait_for(lambda pub=pub, received=received: (pub.publish({"label": "door", "confidence": 0.75}),
                                                                bool(received))[1], timeout=10.0, interval=0.1), name
            assert values_equal(received[-1], namespace["LabelMsg"](label="door", confidence=0.75)), name
            for bad in (12345, {"confidence": 1.0}, {"label": 3, "confidence": 1.0}):
                try:
                    pub.publish(bad)
                except TypeValidationError as exc:
                    assert "Label" in str(exc)
                else:
                    raise AssertionError(f"{name}: {bad!r} was accepted")
            sub.close()
            pub.close()
    assert label_type.validate(label_type.example()).label == "door"
    assert "memory" in ran


def _importable(module: str) -> bool:
    import importlib.util  # noqa: PLC0415

    return importlib.util.find_spec(module) is not None
