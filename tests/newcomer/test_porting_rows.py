"""Item 6 of issue 38: what an upstream recipe writes beyond the rename (docs/porting.md, the issue 38 section)."""

from __future__ import annotations

import logging

import pytest

from agents_core import Launcher, Topic
from agents_core.components import Component
from agents_core.errors import AgentsError, ConfigError


def _ticker(name: str = "ticker") -> Component:
    class Ticker(Component):
        def _execution_step(self, **kwargs: object) -> None:
            pass

    return Ticker(inputs=[], outputs=[], trigger=1.0, component_name=name)


def test_camera_inputs_map_takes_topic_objects() -> None:
    from agents_core.config import VLAConfig  # noqa: PLC0415

    camera = Topic(name="camera", msg_type="Image")
    config = VLAConfig(joint_names_map={"a": "a"}, camera_inputs_map={"front": camera, "wrist": {"name": "wrist"}})
    assert config.camera_inputs_map == {"front": "camera", "wrist": "wrist"}
    config.camera_inputs_map = {"side": Topic(name="side_cam", msg_type="Image")}
    assert config.camera_inputs_map == {"side": "side_cam"}


def test_add_pkg_takes_ros_log_level() -> None:
    ticker = _ticker()
    launcher = Launcher("memory")
    launcher.add_pkg(components=[ticker], ros_log_level="warn", package_name="my_pkg",
                     executable_entry_point="executable")
    assert ticker.config.log_level == "warning"
    with launcher:
        assert logging.getLogger("agents_core.ticker").getEffectiveLevel() == logging.WARNING


def test_add_pkg_refuses_an_unknown_argument_by_name() -> None:
    with pytest.raises(ConfigError, match=r"add_pkg\(\) got unexpected argument\(s\) \['multiprocesing'\]; "
                                          r"it takes components, events_actions, multiprocessing"):
        Launcher("memory").add_pkg(components=[_ticker()], multiprocesing=True)
    with pytest.raises(ConfigError, match="ros_log_level='loud'"):
        Launcher("memory").add_pkg(components=[_ticker()], ros_log_level="loud")


def test_a_name_with_a_dash_says_why_and_the_fix() -> None:
    with pytest.raises(AgentsError) as refused:
        _ticker("my-talker")
    text = str(refused.value)
    assert "ROS 2 names" in text and "'-'" in text and "use 'my_talker'" in text
