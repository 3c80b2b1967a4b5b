"""Component runtime on the memory transport: wiring checks, triggers, ordering, serial execution."""

from __future__ import annotations

import time
from typing import Any

import pytest

from agents_core import Event, Launcher, Topic
from agents_core.components import Component, ComponentRunType
from agents_core.errors import ConfigError, LifecycleError, WiringError
from agents_core.ros import Image, QoSConfig, String
from agents_core.status import HealthStatus, LifecycleState
from tests.conftest import wait_for
from tests.recipe_parts import Relay


def launch(*components: Component, **kwargs: Any) -> Launcher:
    launcher = Launcher(transport="memory")
    launcher.add_pkg(components=list(components), **kwargs)
    return launcher


# -- wiring errors --------------------------------------------------------------------------------


def test_trigger_must_be_an_input() -> None:
    a, b = Topic("a", "String"), Topic("b", "String")
    with pytest.raises(WiringError, match=r"'relay'.*trigger topic 'b' is not one of its inputs"):
        Relay(inputs=[a], outputs=[], trigger=b, component_name="relay")


def test_missing_required_input_type_is_named() -> None:
    class NeedsImage(Component):
        def __init__(self, **kw: Any) -> None:
            self.allowed_inputs = {"Required": [Image, [String, Image]]}
            super().__init__(**kw)

    with pytest.raises(WiringError, match=r"'vision' needs an input topic of type Image; got \['text: String'\]"):
        NeedsImage(inputs=[Topic("text", "String")], trigger=1.0, component_name="vision")


def test_wrong_output_type_is_named() -> None:
    with pytest.raises(WiringError, match=r"output topic 'img' has type Image.*accepted: String"):
        Relay(inputs=[Topic("a", "String")], outputs=[Topic("img", "Image")], trigger=1.0, component_name="relay")


def test_bad_triggers_are_rejected() -> None:
    a = Topic("a", "String")
    with pytest.raises(WiringError, match="rate > 0"):
        Relay(inputs=[a], trigger=0.0)
    with pytest.raises(WiringError, match="empty list"):
        Relay(inputs=[a], trigger=[])
    with pytest.raises(WiringError, match="only valid for server components"):
        Relay(inputs=[a], trigger=None)
    with pytest.raises(WiringError, match="must be a rate"):
        Relay(inputs=[a], trigger="a")  # type: ignore[arg-type]
    server = Relay(inputs=[a], trigger=None, run_type="Server")
    assert server.run_type is ComponentRunType.SERVER


def test_duplicate_names_and_unknown_arguments_fail_early() -> None:
    a = Topic("a", "String")
    with pytest.raises(WiringError, match="listed twice"):
        Relay(inputs=[a, a], trigger=1.0)
    with pytest.raises(ConfigError, match="unexpected argument"):
        Relay(inputs=[a], trigger=1.0, colour="blue")
    launcher = Launcher("memory")
    with pytest.raises(WiringError, match="two components are named 'x'"):
        launcher.add_pkg(components=[Relay(inputs=[a], component_name="x"), Relay(inputs=[a], component_name="x")])


def test_topic_trigger_moves_callback_to_trig_callbacks() -> None:
    a, b = Topic("a", "String"), Topic("b", "String")
    relay = Relay(inputs=[a, b], outputs=[], trigger=a)
    assert list(relay.trig_callbacks) == ["a"]
    assert list(relay.callbacks) == ["b"]


# -- triggers -------------------------------------------------------------------------------------


def test_topic_trigger_fires_once_per_message() -> None:
    words, out = Topic("words", "String"), Topic("out", "String")
    relay = Relay(inputs=[words], outputs=[out], trigger=words, component_name="relay")
    with launch(relay) as launcher:
        got: list[str] = []
        launcher.transport.create_subscription(out, got.append)
        pub = launcher.transport.create_publisher(words)
        for w in ["one", "two", "three"]:
            pub.publish(w)
        assert wait_for(lambda: len(got) == 3)
        time.sleep(0.1)
        assert relay.seen == ["one", "two", "three"]
        assert got == ["ONE", "TWO", "THREE"]
        assert all(kw["topic"] == words for kw in relay.step_kwargs)


def test_list_trigger_fires_on_any_listed_topic() -> None:
    a, b, c = Topic("a", "String"), Topic("b", "String"), Topic("c", "String")
    relay = Relay(inputs=[a, b, c], trigger=[a, b], component_name="relay")
    with launch(relay) as launcher:
        t = launcher.transport
        t.create_publisher(a).publish("from a")
        t.create_publisher(b).publish("from b")
        t.create_publisher(c).publish("from c: no trigger")
        assert wait_for(lambda: len(relay.seen) == 2)
        time.sleep(0.1)
        assert sorted(relay.seen) == ["from a", "from b"]
        assert relay.callbacks["c"].get_output() == "from c: no trigger"


def test_timed_trigger_runs_at_its_rate() -> None:
    a = Topic("a", "String")
    relay = Relay(inputs=[a], trigger=20.0, component_name="ticker")
    with launch(relay):
        time.sleep(1.0)
    steps = len(relay.seen)
    # 20 Hz for ~1 s: generous bounds, the machine is shared and noisy.
    assert 10 <= steps <= 25, steps
    assert relay.seen[0] is None  # no input yet: get_output() gives None


def test_event_trigger_fires_when_the_condition_holds() -> None:
    battery, cmd = Topic("battery", "Float32"), Topic("cmd", "String")
    low = Event(name="low_battery", event_condition=battery.msg.data < 0.2, on_change=True)
    relay = Relay(inputs=[cmd], trigger=low, component_name="on_low")
    with launch(relay) as launcher:
        pub = launcher.transport.create_publisher(battery)
        for level in [0.9, 0.5, 0.15, 0.1, 0.05, 0.8, 0.1]:
            pub.publish(level)
        # Turns true twice (0.15 after 0.5, 0.1 after 0.8); on_change ignores 0.1 and 0.05 in between.
        assert wait_for(lambda: len(relay.seen) == 2)
        time.sleep(0.2)
        assert len(relay.seen) == 2
        assert low.fired == 2
        assert all(kw["event"] is low for kw in relay.step_kwargs)


# -- ordering and serial execution ------------------------------------------------------------------


def test_chain_delivers_in_order() -> None:
    q = QoSConfig(depth=200)
    a, b, c = Topic("a", "String", qos_profile=q), Topic("b", "String", qos_profile=q), Topic("c", "String",
                                                                                              qos_profile=q)
    first = Relay(inputs=[a], outputs=[b], trigger=a, component_name="first", transform=lambda s: s + ">1")
    second = Relay(inputs=[b], outputs=[c], trigger=b, component_name="second", transform=lambda s: s + ">2")
    first.config.execution_queue_depth = 200
    second.config.execution_queue_depth = 200
    with launch(first, second) as launcher:
        got: list[str] = []
        launcher.transport.create_subscription(c, got.append)
        pub = launcher.transport.create_publisher(a)
        for i in range(100):
            pub.publish(str(i))
        assert wait_for(lambda: len(got) == 100, timeout=10.0)
    assert got == [f"{i}>1>2" for i in range(100)]


def test_burst_into_slow_component_is_serial_and_accounted() -> None:
    depth = 5
    # Drops can happen at both layers: the subscription queue (50) and the worker's step queue (5).
    words = Topic("burst", "String", qos_profile=QoSConfig(depth=50))
    relay = Relay(inputs=[words], trigger=words, component_name="slow", step_seconds=0.002)
    relay.config.execution_queue_depth = depth
    with launch(relay) as launcher:
        pub = launcher.transport.create_publisher(words)
        for i in range(1000):
            pub.publish(str(i))
        memory = launcher.transport
        assert memory.wait_for_idle(timeout=20.0)  # type: ignore[attr-defined]
        assert wait_for(lambda: relay.worker_statistics().pending == 0, timeout=20.0)
        topic_stats = memory.statistics()["burst"]  # type: ignore[attr-defined]
        worker = relay.worker_statistics()
    assert relay.max_concurrent == 1, "two steps of one component ran at once"
    assert relay.step_threads == {"worker:slow"}, "steps must run on the component's own worker"
    # Transport: every message delivered to the component or dropped by the subscription queue.
    assert topic_stats.published == 1000
    assert topic_stats.delivered + topic_stats.dropped == 1000
    # Worker: every delivered message became a step that ran or was dropped by the queue policy.
    assert worker.submitted == topic_stats.delivered
    assert worker.executed + worker.dropped + worker.discarded == worker.submitted
    assert len(relay.seen) == worker.executed
    assert topic_stats.dropped + worker.dropped + worker.discarded == 1000 - len(relay.seen)
    assert worker.dropped > 0, "the burst should overflow the worker queue too"
    assert relay.seen[-1] == "999", "drop-oldest keeps the newest message"
    # And the messages processed are in order.
    numbers = [int(s) for s in relay.seen]
    assert numbers == sorted(numbers)


def test_drop_newest_policy_keeps_the_oldest_pending() -> None:
    words = Topic("burst", "String", qos_profile=QoSConfig(depth=1000))
    relay = Relay(inputs=[words], trigger=words, component_name="slow", step_seconds=0.01)
    relay.config.execution_queue_depth = 3
    relay.config.queue_full_policy = "drop_newest"
    with launch(relay) as launcher:
        pub = launcher.transport.create_publisher(words)
        for i in range(50):
            pub.publish(str(i))
        assert wait_for(lambda: relay.worker_statistics().submitted == 50 and
                        relay.worker_statistics().pending == 0, timeout=10.0)
    assert relay.seen[:2] == ["0", "1"]
    assert "49" not in relay.seen
    assert relay.worker_statistics().dropped == 50 - len(relay.seen)


# -- lifecycle ----------------------------------------------------------------------------------


def test_lifecycle_transitions_and_status() -> None:
    words, out = Topic("words", "String"), Topic("out", "String")
    relay = Relay(inputs=[words], outputs=[out], trigger=words, component_name="relay")
    with launch(relay) as launcher:
        t = launcher.transport
        statuses: list[Any] = []
        t.create_subscription(relay.status_topic, statuses.append)
        assert relay.lifecycle_state is LifecycleState.ACTIVE
        assert t.request_transition("relay", "deactivate") is True
        assert relay.lifecycle_state is LifecycleState.INACTIVE
        t.create_publisher(words).publish("ignored while inactive")
        time.sleep(0.2)
        assert relay.seen == []
        assert t.request_transition("relay", "deactivate") is False  # not allowed from inactive
        with pytest.raises(LifecycleError, match="cannot deactivate from state 'inactive'"):
            relay.deactivate()
        relay.activate()
        t.create_publisher(words).publish("now")
        assert wait_for(lambda: relay.seen == ["now"])
        assert wait_for(lambda: any(s.lifecycle_state == "active" for s in statuses))
        state = t.get_component_state("relay")
        assert state is not None and state.health == HealthStatus.HEALTHY.name
    assert relay.lifecycle_state is LifecycleState.FINALIZED


def test_status_is_published_at_a_modest_rate() -> None:
    a = Topic("a", "String")
    relay = Relay(inputs=[a], trigger=50.0, component_name="busy")
    with launch(relay) as launcher:
        statuses: list[Any] = []
        launcher.transport.create_subscription(relay.status_topic, statuses.append)
        time.sleep(1.5)
    # 50 steps/s but status at the default 1 Hz (+ the latched one + changes), never per step.
    assert 1 <= len(statuses) <= 5, len(statuses)


def test_config_is_copied_per_component() -> None:
    a = Topic("a", "String")
    one = Relay(inputs=[a], component_name="one")
    two = Relay(inputs=[a], component_name="two", config=one.config)
    one.config.status_rate = 5.0
    assert two.config.status_rate == 1.0


def test_publisher_preprocessors_and_callback_postprocessors() -> None:
    words, out = Topic("words", "String"), Topic("out", "String")
    relay = Relay(inputs=[words], outputs=[out], trigger=words, component_name="relay", transform=lambda s: s)
    relay.add_callback_postprocessor(words, lambda s: s.strip())
    relay.add_publisher_preprocessor(out, lambda s: f"<{s}>")
    with pytest.raises(WiringError, match="has no output 'nope'"):
        relay.add_publisher_preprocessor("nope", str)
    with launch(relay) as launcher:
        got: list[str] = []
        launcher.transport.create_subscription(out, got.append)
        launcher.transport.create_publisher(words).publish("  padded  ")
        assert wait_for(lambda: got == ["<padded>"])
