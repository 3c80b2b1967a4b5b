"""Exporting recorded episodes as a LeRobot dataset: our exporter against LeRobot's own dataset writer.

Both write the same frames (5 episodes of ``--steps`` frames: a 6-joint state, a 6-value action and one
``--side`` x ``--side`` camera) into a LeRobotDataset v3.0 folder with the same video codec (libx264):

- ``framework``: the frames recorded by :class:`~agents_core.episodes.EpisodeRecorder` (MCAP), exported by
  :func:`~agents_core.episodes.export_lerobot_dataset` (reads the MCAP files twice, encodes with PyAV);
- ``lerobot``: LeRobot's ``LeRobotDataset.create`` + ``add_frame`` + ``save_episode`` given the same frames
  as numpy arrays (no MCAP to read: its writer alone).

The ratio lerobot / framework of the seconds taken is the figure (> 1: ours is faster); seconds per
episode are printed for both. Needs ``lerobot`` (the ``lerobot`` nox session's environment):
``python -m benchmarks.episodes_export [--steps 200] [--side 96] [--rounds 3]``.
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

os.environ.setdefault("HF_HUB_OFFLINE", "1")
EPISODES = 5
JOINTS = [f"j{i}" for i in range(6)]


def _frames(steps: int, side: int) -> list[list[tuple[np.ndarray, np.ndarray, np.ndarray]]]:
    rng = np.random.default_rng(0)
    base = rng.integers(0, 255, (side, side, 3), dtype=np.uint8)
    return [[(rng.normal(size=6), rng.normal(size=6), np.roll(base, 3 * s, axis=1)) for s in range(steps)]
             for _ in range(EPISODES)]


def _record(directory: Path, frames: list[list[tuple[np.ndarray, np.ndarray, np.ndarray]]]) -> None:
    from agents_core import Topic  # noqa: PLC0415
    from agents_core.episodes import EpisodeRecorder  # noqa: PLC0415
    from agents_core.messages import ImageMsg, JointStateMsg  # noqa: PLC0415
    from agents_core.transport import MemoryTransport  # noqa: PLC0415

    topics = [Topic("joints", "JointState"), Topic("camera", "Image"), Topic("command", "Float64MultiArray")]
    transport = MemoryTransport()
    pubs = [transport.create_publisher(t) for t in topics]
    with EpisodeRecorder(directory).attach(transport, topics) as recorder:
        for episode in frames:
            recorder.start_episode("bench")
            for state, action, image in episode:
                pubs[0].publish(JointStateMsg(name=JOINTS, position=state))
                pubs[1].publish(ImageMsg.from_array(image))
                time.sleep(0.0005)  # the command follows the observation, as an agent's would
                pubs[2].publish(action)
                time.sleep(0.0005)
            recorder.stop_episode()
    transport.close()


def _ours(episodes: Path, out: Path, fps: int) -> float:
    from agents_core.episodes import export_lerobot_dataset  # noqa: PLC0415

    started = time.perf_counter()
    export_lerobot_dataset(episodes, out, repo_id="bench/ours", fps=fps, frame_topic="joints", overwrite=True,
                           features={"observation.state": "joints", "observation.images.cam": "camera",
                                     "action": "command"})
    return time.perf_counter() - started


def _lerobot(frames: list[list[tuple[np.ndarray, np.ndarray, np.ndarray]]], out: Path, fps: int, side: int) -> float:
    from lerobot.datasets.lerobot_dataset import LeRobotDataset  # noqa: PLC0415

    shutil.rmtree(out, ignore_errors=True)
    features = {"observation.state": {"dtype": "float32", "shape": (6,), "names": JOINTS},
                "action": {"dtype": "float32", "shape": (6,), "names": None},
                "observation.images.cam": {"dtype": "video", "shape": (side, side, 3),
                                           "names": ["height", "width", "channels"]}}
    started = time.perf_counter()
    dataset = LeRobotDataset.create("bench/lerobot", fps=fps, features=features, root=out, vcodec="h264",
                                    use_videos=True)
    for episode in frames:
        for state, action, image in episode:
            dataset.add_frame({"observation.state": state.astype(np.float32), "action": action.astype(np.float32),
                               "observation.images.cam": image, "task": "bench"})
        dataset.save_episode()
    dataset.finalize()
    return time.perf_counter() - started


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--steps", type=int, default=200)
    parser.add_argument("--side", type=int, default=96)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--fps", type=int, default=30)
    args = parser.parse_args(argv)
    frames = _frames(args.steps, args.side)
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        _record(root / "episodes", frames)
        ours, theirs = [], []
        for _ in range(args.rounds):  # alternating, so a busy moment of the machine hits both
            ours.append(_ours(root / "episodes", root / "ours", args.fps))
            theirs.append(_lerobot(frames, root / "lerobot", args.fps, args.side))
    a, b = statistics.median(ours), statistics.median(theirs)
    print(f"export of {EPISODES} episodes x {args.steps} frames ({args.side}x{args.side} camera), median of "
          f"{args.rounds}: framework {a:.2f} s ({a / EPISODES:.3f} s/episode), LeRobot's writer {b:.2f} s "
          f"({b / EPISODES:.3f} s/episode); lerobot / framework = {b / a:.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
