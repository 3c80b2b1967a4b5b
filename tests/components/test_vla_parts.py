"""The VLA's building blocks on their own: URDF joint limits and the action-chunk queue."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from agents_core.components.vla.action_chunks import ActionChunkQueue, aggregation_function
from agents_core.components.vla.urdf import JointLimits, joint_limits_from_config, read_urdf_joint_limits
from agents_core.errors import ConfigError

ARM_URDF = """<?xml version="1.0"?>
<robot name="arm">
  <link name="base"/><link name="upper"/><link name="fore"/><link name="hand"/><link name="cam"/>
  <joint name="shoulder" type="revolute">
    <parent link="base"/><child link="upper"/>
    <limit lower="-1.5" upper="1.5" velocity="2.0" effort="10"/>
  </joint>
  <joint name="elbow" type="revolute">
    <parent link="upper"/><child link="fore"/>
    <limit lower="0" upper="2.5" velocity="1.0" effort="5"/>
  </joint>
  <joint name="wrist" type="continuous">
    <parent link="fore"/><child link="hand"/>
    <limit velocity="3.0" effort="1"/>
  </joint>
  <joint name="camera_mount" type="fixed"><parent link="hand"/><child link="cam"/></joint>
</robot>
"""


def write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "arm.urdf"
    path.write_text(text, encoding="utf-8")
    return path


class TestURDFLimits:
    def test_reads_revolute_and_continuous_joints_and_skips_fixed_ones(self, tmp_path: Path) -> None:
        limits = read_urdf_joint_limits(write(tmp_path, ARM_URDF))
        assert limits == {"shoulder": JointLimits(-1.5, 1.5, 2.0), "elbow": JointLimits(0.0, 2.5, 1.0),
                          "wrist": JointLimits(None, None, 3.0)}

    @pytest.mark.parametrize("text, match", [
        ("<robot><joint name='a' type='revolute'/></robot>", "needs a <limit>"),
        ("<robot><joint name='a' type='revolute'><limit lower='x' upper='1' velocity='1'/></joint></robot>",
         "not a number"),
        ("<robot><joint name='a' type='revolute'><limit lower='2' upper='1' velocity='1'/></joint></robot>",
         "above upper"),
        ("<robot><joint name='a' type='revolute'><limit lower='nan' upper='1'/></joint></robot>", "finite"),
        ("<model/>", "expected <robot>"),
        ("<robot>", "not well-formed"),
        ('<?xml version="1.0"?><!DOCTYPE r [<!ENTITY a "aaaa">]><robot>&a;</robot>', "DOCTYPE"),
    ])
    def test_bad_files_are_config_errors(self, tmp_path: Path, text: str, match: str) -> None:
        with pytest.raises(ConfigError, match=match):
            read_urdf_joint_limits(write(tmp_path, text))

    def test_a_missing_file_is_a_config_error(self, tmp_path: Path) -> None:
        with pytest.raises(ConfigError, match="cannot read URDF"):
            read_urdf_joint_limits(tmp_path / "nope.urdf")

    def test_clipping_respects_position_and_velocity_limits(self) -> None:
        limits = JointLimits(-1.0, 1.0, 2.0)
        assert limits.clip_position(5.0, current=None, dt=0.1) == 1.0
        assert limits.clip_position(0.9, current=0.0, dt=0.1) == pytest.approx(0.2)  # 2 rad/s * 0.1 s
        assert limits.clip_position(-0.9, current=0.95, dt=0.1) == pytest.approx(0.75)
        assert limits.clip_velocity(-7.0) == -2.0
        assert JointLimits().clip_position(9.0, current=0.0, dt=1.0) == 9.0

    def test_limits_from_a_config_dict(self) -> None:
        limits = joint_limits_from_config({"a": {"lower": -1, "upper": 1}, "b": {"velocity": 0.5}}, "VLAConfig")
        assert limits == {"a": JointLimits(-1.0, 1.0, None), "b": JointLimits(None, None, 0.5)}
        with pytest.raises(ConfigError, match=r"VLAConfig.joint_limits\['a'\]: unknown key"):
            joint_limits_from_config({"a": {"min": 0}}, "VLAConfig")
        with pytest.raises(ConfigError, match="velocity must be > 0"):
            joint_limits_from_config({"a": {"velocity": 0}}, "VLAConfig")
        with pytest.raises(ConfigError, match="finite number"):
            joint_limits_from_config({"a": {"lower": float("inf")}}, "VLAConfig")


class TestActionChunkQueue:
    def test_plays_actions_in_step_order(self) -> None:
        queue = ActionChunkQueue()
        assert queue.add_chunk(0, [[0.0], [1.0], [2.0]]) == 3
        assert [queue.pop_next()[0] for _ in range(3)] == [0, 1, 2]  # type: ignore[index]
        assert queue.pop_next() is None and queue.last_played == 2

    def test_overlapping_steps_are_aggregated_and_played_ones_dropped(self) -> None:
        queue = ActionChunkQueue("weighted_average")
        queue.add_chunk(0, [[0.0], [10.0], [20.0]])
        step, first = queue.pop_next()  # type: ignore[misc]
        assert step == 0 and first[0] == 0.0
        # A newer chunk from an observation at step 0 again: step 0 is played already, 1 and 2 overlap, 3 is new.
        assert queue.add_chunk(0, [[5.0], [20.0], [30.0], [40.0]]) == 3
        assert queue.dropped_late == 1 and queue.aggregated == 2
        played = [queue.pop_next() for _ in range(3)]
        assert [s for s, _ in played] == [1, 2, 3]  # type: ignore[misc]
        np.testing.assert_allclose([a[0] for _, a in played], [0.3 * 10 + 0.7 * 20, 0.3 * 20 + 0.7 * 30, 40.0])  # type: ignore[misc]

    def test_a_custom_aggregation_function(self) -> None:
        queue = ActionChunkQueue(np.maximum)
        queue.add_chunk(0, [[1.0, 5.0]])
        queue.add_chunk(0, [[3.0, 2.0]])
        np.testing.assert_allclose(queue.pop_next()[1], [3.0, 5.0])  # type: ignore[index]

    def test_unknown_aggregation_names_and_bad_chunks_are_errors(self) -> None:
        with pytest.raises(ConfigError, match="latest_only"):
            aggregation_function("median")
        with pytest.raises(ConfigError, match="2-D"):
            ActionChunkQueue().add_chunk(0, [1.0, 2.0])

    def test_the_queue_is_bounded(self) -> None:
        queue = ActionChunkQueue(max_actions=5)
        queue.add_chunk(0, np.zeros((50, 2)))
        assert len(queue) == 5 and queue.pop_next()[0] == 0  # type: ignore[index]

    def test_clear_forgets_actions_and_sets_the_played_step(self) -> None:
        queue = ActionChunkQueue()
        queue.add_chunk(0, np.zeros((5, 1)))
        queue.clear(last_played=3)
        assert len(queue) == 0
        assert queue.add_chunk(0, np.zeros((6, 1))) == 2
