"""Export recorded episodes as a LeRobotDataset v3.0 folder, read back with pyarrow and PyAV (no LeRobot here).

LeRobot's own ``LeRobotDataset`` reads the same folders in ``tests/lerobot`` (the ``lerobot`` nox session).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("mcap", reason="pip install 'agents-core[record]'")
pq = pytest.importorskip("pyarrow.parquet", reason="pip install 'agents-core[dataset]'")
av = pytest.importorskip("av", reason="pip install 'agents-core[dataset]'")

from agents_core.episodes import LeRobotFeature, export_lerobot_dataset, load_episodes  # noqa: E402
from agents_core.errors import ConfigError  # noqa: E402
from agents_core.recording import read_recording  # noqa: E402

from .dataset_parts import FEATURES, FPS, HEIGHT, JOINT_NAMES, WIDTH, Recorded, record_episodes  # noqa: E402


@pytest.fixture(scope="module")
def recorded(tmp_path_factory: pytest.TempPathFactory) -> Recorded:
    return record_episodes(tmp_path_factory.mktemp("episodes"))


def _decode(path: Path) -> tuple[list[np.ndarray], list[float]]:
    with av.open(str(path)) as container:
        frames = list(container.decode(video=0))
        return [f.to_ndarray(format="rgb24") for f in frames], [float(f.pts * f.time_base) for f in frames]


def test_the_folder_has_the_v3_layout_and_the_recorded_frames(recorded: Recorded, tmp_path: Path) -> None:  # noqa: PLR0915
    out = tmp_path / "ds"
    summary = export_lerobot_dataset(recorded.directory, out, repo_id="agents/test", fps=FPS, frame_topic="joints",
                                     features=FEATURES, robot_type="arm3")
    total = sum(recorded.steps)
    assert summary.episodes == 5 and summary.frames == total and not summary.skipped
    for part in ("meta/info.json", "meta/stats.json", "meta/tasks.parquet", "meta/episodes/chunk-000/file-000.parquet",
                 "data/chunk-000/file-000.parquet", "videos/observation.images.top/chunk-000/file-000.mp4"):
        assert (out / part).is_file(), part
    info = json.loads((out / "meta/info.json").read_text())
    assert info["codebase_version"] == "v3.0" and info["fps"] == FPS and info["robot_type"] == "arm3"
    assert (info["total_episodes"], info["total_frames"], info["total_tasks"]) == (5, total, 2)
    assert info["splits"] == {"train": "0:5"}
    assert info["data_path"] == "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet"
    assert info["video_path"] == "videos/{video_key}/chunk-{chunk_index:03d}/file-{file_index:03d}.mp4"
    features = info["features"]
    assert features["observation.state"] == {"dtype": "float32", "shape": [3], "names": JOINT_NAMES}
    assert features["action"] == {"dtype": "float32", "shape": [4], "names": None}
    video = features["observation.images.top"]
    assert video["dtype"] == "video" and video["shape"] == [HEIGHT, WIDTH, 3]
    assert video["info"]["video.codec"] == "h264" and video["info"]["video.fps"] == FPS
    assert {"timestamp", "frame_index", "episode_index", "index", "task_index"} <= set(features)

    tasks = pq.read_table(out / "meta/tasks.parquet").to_pydict()
    assert tasks == {"task_index": [0, 1], "__index_level_0__": ["reach the target", "wave"]}
    episodes = pq.read_table(out / "meta/episodes/chunk-000/file-000.parquet").to_pydict()
    assert episodes["length"] == recorded.steps and episodes["episode_index"] == [0, 1, 2, 3, 4]
    assert episodes["tasks"] == [[t] for t in recorded.tasks]
    bounds = np.cumsum([0, *recorded.steps])
    assert episodes["dataset_from_index"] == bounds[:-1].tolist()
    assert episodes["dataset_to_index"] == bounds[1:].tolist()
    assert episodes["videos/observation.images.top/from_timestamp"] == (bounds[:-1] / FPS).tolist()
    assert episodes["videos/observation.images.top/to_timestamp"] == (bounds[1:] / FPS).tolist()

    data = pq.read_table(out / "data/chunk-000/file-000.parquet").to_pydict()
    assert data["index"] == list(range(total))
    row = 0
    for e, steps in enumerate(recorded.steps):
        for s in range(steps):
            assert data["episode_index"][row] == e and data["frame_index"][row] == s
            assert data["timestamp"][row] == pytest.approx(s / FPS)
            assert data["task_index"][row] == (0 if e % 2 == 0 else 1)
            np.testing.assert_array_equal(data["observation.state"][row], recorded.states[e][s].astype(np.float32))
            np.testing.assert_array_equal(data["action"][row], recorded.actions[e][s].astype(np.float32))
            row += 1

    frames, times = _decode(out / "videos/observation.images.top/chunk-000/file-000.mp4")
    assert len(frames) == total
    assert times == pytest.approx([k / FPS for k in range(total)])
    expected = [img for episode in recorded.images for img in episode]
    errors = [float(np.abs(f.astype(int) - x.astype(int)).mean()) for f, x in zip(frames, expected, strict=True)]
    assert max(errors) < 3.0, errors

    stats = json.loads((out / "meta/stats.json").read_text())
    states = np.concatenate([np.array(s, np.float32) for s in recorded.states])
    assert stats["observation.state"]["min"] == pytest.approx(states.min(axis=0).tolist(), abs=1e-6)
    assert stats["observation.state"]["mean"] == pytest.approx(states.mean(axis=0).tolist(), abs=1e-5)
    assert stats["observation.state"]["count"] == [total]
    assert np.array(stats["observation.images.top"]["mean"]).shape == (3, 1, 1)
    assert 0 <= np.min(stats["observation.images.top"]["min"]) <= np.max(stats["observation.images.top"]["max"]) <= 1
    assert summary.seconds > 0


def test_without_a_frame_topic_frames_follow_the_clock(recorded: Recorded, tmp_path: Path) -> None:
    first = load_episodes(recorded.directory)[:1]
    summary = export_lerobot_dataset(first, tmp_path / "ds", repo_id="agents/clock", fps=100,
                                     features={"observation.state": "joints", "action": "command"})
    messages = list(read_recording(first[0].mcap))
    joints = [(m.log_time_ns, m.value.position) for m in messages if m.topic == "joints"]
    commands = [(m.log_time_ns, m.value) for m in messages if m.topic == "command"]
    start = max(joints[0][0], commands[0][0])
    data = pq.read_table(tmp_path / "ds/data/chunk-000/file-000.parquet").to_pydict()
    assert summary.frames == len(data["index"]) > 2 * len(joints)  # 100 Hz from a 40 Hz recording
    for k, (st, act) in enumerate(zip(data["observation.state"], data["action"], strict=True)):
        t = start + k * 10**9 // 100
        np.testing.assert_array_equal(st, [p for ts, p in joints if ts <= t][-1].astype(np.float32))
        np.testing.assert_array_equal(act, [v for ts, v in commands if ts <= t][-1].astype(np.float32))


def test_bad_requests_are_named(recorded: Recorded, tmp_path: Path) -> None:
    def export(**kwargs: object) -> object:
        options: dict[str, object] = {"repo_id": "agents/x", "fps": FPS, "features": FEATURES, **kwargs}
        return export_lerobot_dataset(recorded.directory, tmp_path / "ds", **options)  # type: ignore[arg-type]

    with pytest.raises(ConfigError, match=r"'observation\.cam': a camera \(Image on 'top'\) is named"):
        export(features={"observation.cam": "top"})
    with pytest.raises(ConfigError, match=r"topic 'nope' is in none of the episodes"):
        export(features={"action": "nope"})
    with pytest.raises(ConfigError, match="fps must be a positive integer"):
        export(fps=20.5)
    with pytest.raises(ConfigError, match="'user/name'"):
        export(repo_id="plain")
    with pytest.raises(ConfigError, match="is one LeRobot writes itself"):
        export(features={"timestamp": "joints"})
    with pytest.raises(ConfigError, match="a JointState field is position, velocity or effort"):
        export(features={"observation.state": LeRobotFeature("joints", field="torque")})
    with pytest.raises(ConfigError, match=r"episode 0 has vectors of lengths \[0\] \(from 'joints'"):
        export(features={"observation.state": LeRobotFeature("joints", field="velocity")})
    assert not (tmp_path / "ds").exists()  # a failed export leaves no half-written folder
    export(features={"observation.state": "joints"})
    with pytest.raises(ConfigError, match="exists; pass overwrite=True"):
        export(features={"observation.state": "joints"})
    assert export(features={"observation.state": "joints"}, overwrite=True).episodes == 5  # type: ignore[attr-defined]
