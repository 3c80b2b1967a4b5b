"""Recorded episodes -> a LeRobotDataset v3.0 folder (``pip install 'agents-core[dataset]'``: pyarrow, PyAV).

:func:`export_lerobot_dataset` maps topics to LeRobot features — a vector (``observation.state``,
``action``, ...) from a JointState (its ``position`` unless ``field`` says ``velocity`` / ``effort``),
a Float32/Float64 array or scalar, a Twist (linear then angular), and a camera
(``observation.images.<cam>``) from an Image or RGBD — and writes the folder :mod:`.lerobot_format`
describes, loadable by LeRobot's own ``LeRobotDataset(repo_id, root=out_dir)`` without the hub.

Frames. With ``frame_topic``, one frame per message of that topic (the world's observation of each
step); without, one frame every ``1 / fps`` seconds from the moment every feature has a value.
An observation feature takes its topic's latest message at or before the frame's time, give or take
``tolerance_s`` (receipt times: the recorder's clock, the same for every topic); an ``action*`` feature takes, with
``frame_topic``, the first message after the frame and before the next one (the agent's answer to
that observation; failing that the latest before), and without it the latest at or before the
frame. A frame's ``timestamp`` is ``frame_index / fps``, as LeRobot requires, which is where its
video frame sits.

Memory: an episode is read twice (its times and vectors first, then its camera frames, each encoded
as it arrives), so no episode's images are held at once; vectors are float32.
"""

from __future__ import annotations

import bisect
import logging
import os
import shutil
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, cast

from attrs import define, field

from ..errors import ConfigError
from ..recording.reader import read_recording
from ..support.lazy_numpy import np, npt
from . import lerobot_format as fmt
from .recorder import EpisodeInfo, load_episodes

__all__ = ["ExportSummary", "LeRobotFeature", "export_lerobot_dataset"]

logger = logging.getLogger(__name__)

_IMAGE_TYPES = ("Image", "RGBD", "CompressedImage")
_VECTOR_TYPES = ("JointState", "Float32MultiArray", "Float64MultiArray", "Float32", "Float64", "Int32", "Int64",
                 "Bool", "Twist")


@define(frozen=True)
class LeRobotFeature:
    """Where one LeRobot feature comes from.

    :param topic: the recorded topic.
    :param field: for a JointState: ``position`` (default), ``velocity`` or ``effort``; for other
        types, an attribute of the value.
    :param names: the names of the vector's entries (default: a JointState's joint names, else none).
    """

    topic: str
    field: str | None = None
    names: Sequence[str] | None = None


@define
class ExportSummary:
    """What an export wrote: the folder, episodes, frames, seconds it took, and per-episode notes."""

    root: Path
    episodes: int = 0
    frames: int = 0
    seconds: float = 0.0
    skipped: dict[int, str] = field(factory=dict)
    features: dict[str, dict[str, Any]] = field(factory=dict)


def _vector(key: str, topic: str, type_name: str, value: Any, field_name: str | None) -> npt.NDArray[np.float32]:
    if field_name is not None and type_name != "JointState":
        part = getattr(value, field_name, None)
        if part is None:
            raise ConfigError(f"feature {key!r}: a {type_name} on {topic!r} has no field {field_name!r}")
        return np.asarray(part, np.float32).ravel()
    if type_name == "JointState":
        name = field_name or "position"
        if name not in ("position", "velocity", "effort"):
            raise ConfigError(f"feature {key!r}: a JointState field is position, velocity or effort, not {name!r}")
        return np.asarray(getattr(value, name), np.float32).ravel()
    if type_name == "Twist":
        return np.concatenate([np.asarray(value.linear, np.float32), np.asarray(value.angular, np.float32)])
    if type_name in _VECTOR_TYPES:
        return np.asarray(value, np.float32).ravel()
    raise ConfigError(f"feature {key!r}: topic {topic!r} carries {type_name}, which is not a vector "
                      f"({', '.join(_VECTOR_TYPES)}) nor a camera ({', '.join(_IMAGE_TYPES)})")


def _rgb(key: str, topic: str, value: Any) -> npt.NDArray[np.uint8]:
    if hasattr(value, "format") and isinstance(getattr(value, "data", None), bytes):  # CompressedImage
        try:
            import io  # noqa: PLC0415

            from PIL import Image as PILImage  # noqa: PLC0415 - Pillow, with the 'dataset' extra
        except ImportError as exc:
            raise ConfigError(f"feature {key!r}: decoding CompressedImage needs Pillow ({exc})") from None
        return np.asarray(PILImage.open(io.BytesIO(value.data)).convert("RGB"), np.uint8)
    pixels = np.asarray(value.to_rgb())
    if pixels.ndim == 2:
        pixels = pixels[:, :, None]
    if pixels.dtype != np.uint8:
        raise ConfigError(f"feature {key!r}: camera frames on {topic!r} are {pixels.dtype}, not 8-bit colour "
                          "(depth images do not go into a LeRobot video)")
    if pixels.shape[2] == 1:
        pixels = np.repeat(pixels, 3, axis=2)
    return np.ascontiguousarray(pixels[:, :, :3])


class _VideoFile:
    """One camera's mp4 (PyAV), frames appended across episodes with pts = frame number at 1/fps."""

    def __init__(self, path: Path, fps: int, width: int, height: int, vcodec: str, crf: int, gop: int) -> None:
        try:
            import av  # noqa: PLC0415 - PyAV, the 'dataset' extra
        except ImportError as exc:
            raise ConfigError(f"exporting videos needs PyAV, the 'dataset' extra ({exc}); "
                              "pip install 'agents-core[dataset]'") from None
        if width % 2 or height % 2:
            raise ConfigError(f"video {path.parent.parent.name!r}: {width}x{height} frames; yuv420p video needs "
                              "an even width and height")
        self._av = av
        path.parent.mkdir(parents=True, exist_ok=True)
        self.path = path
        self.size = (width, height)
        self._container: Any = cast(Any, av.open(str(path), "w"))
        options = {"g": str(gop), "crf": str(crf)}
        if vcodec in ("libx264", "h264"):
            options["bf"] = "0"  # no B-frames: decode order = presentation order, no edit list
        self._stream: Any = cast(Any, self._container.add_stream(vcodec, rate=fps, options=options))
        self._stream.width, self._stream.height, self._stream.pix_fmt = width, height, "yuv420p"
        from fractions import Fraction  # noqa: PLC0415

        self._stream.time_base = Fraction(1, fps)
        self.frames = 0

    def add(self, pixels: npt.NDArray[np.uint8]) -> None:
        if (pixels.shape[1], pixels.shape[0]) != self.size:
            raise ConfigError(f"video {self.path}: a {pixels.shape[1]}x{pixels.shape[0]} frame in a "
                              f"{self.size[0]}x{self.size[1]} video (a camera changed resolution)")
        frame = self._av.VideoFrame.from_ndarray(pixels, format="rgb24")
        frame.pts = self.frames
        for packet in self._stream.encode(frame):
            self._container.mux(packet)
        self.frames += 1

    def close(self) -> None:
        for packet in self._stream.encode():
            self._container.mux(packet)
        self._container.close()


def _video_info(path: Path, fps: int) -> dict[str, Any]:
    import av  # noqa: PLC0415

    with av.open(str(path)) as container:
        stream: Any = cast(Any, container.streams.video[0])
        return {"video.height": stream.height, "video.width": stream.width,
                "video.codec": stream.codec_context.codec.canonical_name, "video.pix_fmt": stream.pix_fmt,
                "video.is_depth_map": False, "video.fps": fps, "video.channels": 3, "has_audio": False}


@define
class _Plan:
    """One episode's frames: per feature, the message index each frame takes."""

    frames: int
    picks: dict[str, list[int]]
    vectors: dict[str, list[npt.NDArray[np.float32]]]
    names: dict[str, list[str] | None]
    images: dict[str, tuple[str, list[int]]]  # key -> (topic, message index per frame)


def _plan(info: EpisodeInfo, specs: Mapping[str, LeRobotFeature], kinds: Mapping[str, str], fps: int,
          frame_topic: str | None, tolerance_s: float) -> _Plan | str:
    """Pass 1 over one episode: times and vectors, then which message each frame takes (or why none)."""
    topics = {spec.topic for spec in specs.values()} | ({frame_topic} if frame_topic else set())
    times: dict[str, list[int]] = {t: [] for t in topics}
    vectors: dict[str, list[npt.NDArray[np.float32]]] = {k: [] for k in specs if kinds[k] == "vector"}
    names: dict[str, list[str] | None] = {k: (list(s.names) if s.names else None) for k, s in specs.items()}
    for message in read_recording(info.mcap, topics=topics):
        times[message.topic].append(message.log_time_ns)
        for key, spec in specs.items():
            if spec.topic != message.topic or kinds[key] != "vector":
                continue
            type_name = message.msg_type.type_name()
            vectors[key].append(_vector(key, spec.topic, type_name, message.value, spec.field))
            if names[key] is None and type_name == "JointState" and spec.field in (None, "position", "velocity",
                                                                                  "effort"):
                names[key] = [str(n) for n in message.value.name] or None
    missing = sorted(t for t, ts in times.items() if not ts)
    if missing:
        return f"no message on {', '.join(map(repr, missing))}"
    if frame_topic:
        frame_times = times[frame_topic]
    else:
        start = max(ts[0] for ts in times.values())
        end = max(ts[-1] for ts in times.values())
        # Integer nanoseconds: a float of ~1.7e18 ns would be off by a hundred ns.
        frame_times = [start + k * 10**9 // fps for k in range((end - start) * fps // 10**9 + 1)]
    picks: dict[str, list[int]] = {k: [] for k in specs}
    tolerance = int(tolerance_s * 1e9)
    kept = 0
    for n, t in enumerate(frame_times):
        following = frame_times[n + 1] if n + 1 < len(frame_times) else 2**63
        chosen: dict[str, int] = {}
        for key, spec in specs.items():
            ts = times[spec.topic]
            if key.startswith("action"):
                pick = latest = bisect.bisect_right(ts, t) - 1
                if frame_topic and latest + 1 < len(ts) and ts[latest + 1] <= following:
                    pick = latest + 1
            else:
                pick = bisect.bisect_right(ts, min(t + tolerance, following - 1)) - 1
            if pick < 0:
                break
            chosen[key] = pick
        else:
            for key, pick in chosen.items():
                picks[key].append(pick)
            kept += 1
    if not kept:
        return "no frame has a value of every feature"
    images = {k: (specs[k].topic, picks[k]) for k in specs if kinds[k] == "video"}
    return _Plan(kept, picks, vectors, names, images)


def _as_specs(features: Mapping[str, str | LeRobotFeature]) -> dict[str, LeRobotFeature]:
    specs: dict[str, LeRobotFeature] = {}
    for key, spec in features.items():
        if not isinstance(key, str) or not key or "/" in key:
            raise ConfigError(f"feature name {key!r}: a LeRobot feature is a name without '/'")
        if key in fmt.DEFAULT_FEATURES:
            raise ConfigError(f"feature name {key!r} is one LeRobot writes itself")
        specs[key] = LeRobotFeature(spec) if isinstance(spec, str) else spec
        if not isinstance(specs[key], LeRobotFeature):
            raise ConfigError(f"feature {key!r}: give a topic name or a LeRobotFeature, not {type(spec).__name__}")
    if not specs:
        raise ConfigError("export_lerobot_dataset: no features given")
    return specs


def export_lerobot_dataset(episodes: Sequence[EpisodeInfo] | str | os.PathLike[str], out_dir: str | os.PathLike[str],
                           *, repo_id: str, fps: int, features: Mapping[str, str | LeRobotFeature],
                           frame_topic: str | None = None, tolerance_s: float | None = None,
                           robot_type: str | None = None,
                           vcodec: str = "libx264", crf: int = 18, gop: int = 2,
                           overwrite: bool = False) -> ExportSummary:
    """Write ``episodes`` (infos, or a folder of them) as a LeRobotDataset v3.0 at ``out_dir``.

    :param repo_id: the dataset's name (``user/name``), as LeRobot's ``LeRobotDataset(repo_id, root=...)`` takes.
    :param fps: frames per second (an integer, as LeRobot requires).
    :param features: LeRobot feature name -> topic name or :class:`LeRobotFeature`; cameras are
        ``observation.images.<cam>`` (any feature on an Image topic becomes a video).
    :param frame_topic: one frame per message of this topic; None: frames every ``1 / fps`` s.
    :param tolerance_s: an observation published up to this long after the frame's time still belongs to
        it (a world publishes its state and its camera one after the other); default: half a frame
        (``0.5 / fps``) with ``frame_topic``, 0 without. Never past the next frame.
    :param vcodec: the video encoder (``libx264``, or ``libsvtav1`` as LeRobot records); ``crf``, ``gop``:
        its quality and keyframe interval (2, as LeRobot, for quick random access).
    :param overwrite: replace an existing ``out_dir``; otherwise one that exists is refused.

    An episode with no frame (a feature's topic never appears in it) is skipped and named in
    :attr:`ExportSummary.skipped`. Raises ConfigError for a feature whose topic carries an unusable type.
    """
    started = time.monotonic()
    pa = fmt.require_pyarrow()
    if not isinstance(fps, int) or fps <= 0:
        raise ConfigError(f"fps must be a positive integer (LeRobot's frame rate), got {fps!r}")
    if "/" not in repo_id:
        raise ConfigError(f"repo_id {repo_id!r}: LeRobot names a dataset 'user/name'")
    specs = _as_specs(features)
    infos = load_episodes(episodes) if isinstance(episodes, (str, os.PathLike)) else list(episodes)
    kinds = _kinds(specs, infos)
    root = Path(out_dir)
    if root.exists():
        if not overwrite:
            raise ConfigError(f"{root} exists; pass overwrite=True (--overwrite) to replace it")
        shutil.rmtree(root)
    if tolerance_s is None:
        tolerance_s = 0.5 / fps if frame_topic else 0.0
    root.mkdir(parents=True)
    writer = _Writer(root, pa, specs, kinds, fps, frame_topic, vcodec, crf, gop)
    writer.tolerance_s = float(tolerance_s)
    try:
        summary = writer.run(infos, robot_type)
    except BaseException:
        shutil.rmtree(root, ignore_errors=True)  # no half-written dataset left to be mistaken for one
        raise
    summary.seconds = time.monotonic() - started
    return summary


def _kinds(specs: Mapping[str, LeRobotFeature], infos: Sequence[EpisodeInfo]) -> dict[str, str]:
    """Each feature's kind, ``vector`` or ``video``, from the type its topic has in the episodes."""
    kinds: dict[str, str] = {}
    for key, spec in specs.items():
        types = {e.topics[spec.topic]["type"] for e in infos if spec.topic in e.topics}
        if not types:
            raise ConfigError(f"feature {key!r}: topic {spec.topic!r} is in none of the episodes "
                              f"(they hold {sorted({t for e in infos for t in e.topics})})")
        if len(types) > 1:
            raise ConfigError(f"feature {key!r}: topic {spec.topic!r} has several types {sorted(types)}")
        type_name = types.pop()
        if type_name in _IMAGE_TYPES:
            if not key.startswith("observation.images."):
                raise ConfigError(f"feature {key!r}: a camera ({type_name} on {spec.topic!r}) is named "
                                  "'observation.images.<cam>'")
            kinds[key] = "video"
        elif type_name in _VECTOR_TYPES or spec.field is not None:
            kinds[key] = "vector"
        else:
            raise ConfigError(f"feature {key!r}: topic {spec.topic!r} carries {type_name}, which is not a vector "
                              f"({', '.join(_VECTOR_TYPES)}) nor a camera ({', '.join(_IMAGE_TYPES)})")
    return kinds


class _Writer:
    """The export of one dataset: episodes appended to one data file and one video per camera."""

    def __init__(self, root: Path, pa: Any, specs: Mapping[str, LeRobotFeature], kinds: Mapping[str, str], fps: int,
                 frame_topic: str | None, vcodec: str, crf: int, gop: int) -> None:
        self.root, self.pa, self.specs, self.kinds, self.fps = root, pa, specs, kinds, fps
        self.frame_topic, self.vcodec, self.crf, self.gop = frame_topic, vcodec, crf, gop
        self.tolerance_s = 0.0
        self.features: dict[str, dict[str, Any]] = {}
        self.videos: dict[str, _VideoFile] = {}
        self.video_files: dict[str, tuple[int, int]] = {}
        self.checked: set[str] = set()  # cameras whose file was checked against its size limit this episode
        self.data_file = (0, 0)
        self.data_writer: Any = None
        self.data_bytes = 0
        self.tasks: list[str] = []
        self.rows: list[dict[str, Any]] = []
        self.episode_stats: list[dict[str, dict[str, npt.NDArray[Any]]]] = []
        self.total_frames = 0

    def run(self, infos: Sequence[EpisodeInfo], robot_type: str | None) -> ExportSummary:
        summary = ExportSummary(root=self.root)
        try:
            for info in infos:
                plan = _plan(info, self.specs, self.kinds, self.fps, self.frame_topic, self.tolerance_s)
                if isinstance(plan, str):
                    summary.skipped[info.episode] = plan
                    logger.warning("export: episode %d skipped: %s", info.episode, plan)
                    continue
                self._episode(info, plan, len(self.rows))
        finally:
            if self.data_writer is not None:
                self.data_writer.close()
            for video in self.videos.values():
                video.close()
        if not self.rows:
            raise ConfigError(f"no episode could be exported ({summary.skipped})")
        for key in self.videos:
            first = self.root / fmt.video_path(key, 0, 0)
            self.features[key]["info"] = _video_info(first, self.fps)
        fmt.write_tasks(self.root, self.tasks)
        fmt.write_episodes_table(self.root, self.rows)
        stats = {key: fmt.StatsAccumulator.merge([e[key] for e in self.episode_stats]) for key in self.episode_stats[0]}
        fmt.write_json(self.root / "meta" / "stats.json", fmt.stats_json(stats))
        fmt.write_json(self.root / "meta" / "info.json", fmt.info_document(
            fps=self.fps, features=self.features, total_episodes=len(self.rows), total_frames=self.total_frames,
            total_tasks=len(self.tasks), robot_type=robot_type, has_video=bool(self.videos)))
        summary.episodes, summary.frames, summary.features = len(self.rows), self.total_frames, self.features
        return summary

    def _episode(self, info: EpisodeInfo, plan: _Plan, index: int) -> None:
        task = info.task or ""
        if task not in self.tasks:
            self.tasks.append(task)
        n = plan.frames
        first = self.total_frames
        columns: dict[str, Any] = {}
        stats: dict[str, dict[str, npt.NDArray[Any]]] = {}
        for key, values in plan.vectors.items():
            rows = [values[i] for i in plan.picks[key]]
            width = {len(r) for r in rows}
            if len(width) != 1 or 0 in width:
                raise ConfigError(f"feature {key!r}: episode {info.episode} has vectors of lengths {sorted(width)} "
                                  f"(from {self.specs[key].topic!r}; an empty field of a JointState?)")
            matrix = np.stack(rows).astype(np.float32)
            self._declare(key, {"dtype": "float32", "shape": [matrix.shape[1]], "names": plan.names[key]},
                          info.episode)
            columns[key] = self.pa.FixedSizeListArray.from_arrays(self.pa.array(matrix.ravel(), self.pa.float32()),
                                                                  matrix.shape[1])
            stats[key] = fmt.StatsAccumulator.of_column(matrix)
        defaults = {"timestamp": np.arange(n, dtype=np.float32) / np.float32(self.fps),
                    "frame_index": np.arange(n, dtype=np.int64),
                    "episode_index": np.full(n, index, np.int64),
                    "index": np.arange(first, first + n, dtype=np.int64),
                    "task_index": np.full(n, self.tasks.index(task), np.int64)}
        for name, array in defaults.items():
            columns[name] = self.pa.array(array)
            stats[name] = fmt.StatsAccumulator.of_column(array)
        row: dict[str, Any] = {"episode_index": index, "tasks": [task], "length": n}
        row.update(self._write_videos(info, plan, stats))
        row.update(self._write_data(self.pa.table(columns), first, n))
        row["meta/episodes/chunk_index"], row["meta/episodes/file_index"] = 0, 0
        for key, feature_stats in stats.items():
            for name, value in feature_stats.items():
                row[f"stats/{key}/{name}"] = value
        self.rows.append(row)
        self.episode_stats.append(stats)
        self.total_frames += n

    def _declare(self, key: str, feature: dict[str, Any], episode: int) -> None:
        known = self.features.setdefault(key, feature)
        if known["shape"] != feature["shape"]:
            raise ConfigError(f"feature {key!r}: episode {episode} has shape {feature['shape']}, "
                              f"earlier ones {known['shape']}")

    def _write_data(self, table: Any, first: int, n: int) -> dict[str, Any]:
        if self.data_writer is not None and self.data_bytes >= fmt.DATA_FILE_MB * 2**20:
            self.data_writer.close()
            self.data_writer, self.data_bytes = None, 0
            self.data_file = fmt.next_file(*self.data_file)
        if self.data_writer is None:
            path = self.root / fmt.data_path(*self.data_file)
            path.parent.mkdir(parents=True, exist_ok=True)
            self.data_writer = self.pa.parquet.ParquetWriter(path, table.schema, compression="snappy")
        self.data_writer.write_table(table)
        self.data_bytes += table.nbytes
        return {"data/chunk_index": self.data_file[0], "data/file_index": self.data_file[1],
                "dataset_from_index": first, "dataset_to_index": first + n}

    def _write_videos(self, info: EpisodeInfo, plan: _Plan, stats: dict[str, dict[str, npt.NDArray[Any]]]
                      ) -> dict[str, Any]:
        """Pass 2: each camera's frames encoded as their messages arrive; returns the episode's video columns."""
        if not plan.images:
            return {}
        wanted: dict[str, list[str]] = {}
        for key, (topic, _) in plan.images.items():
            wanted.setdefault(topic, []).append(key)
        self.checked = set()
        seen = dict.fromkeys(wanted, -1)
        cursor = dict.fromkeys(plan.images, 0)
        starts: dict[str, int] = {}
        samples = {key: set(np.linspace(0, plan.frames - 1, min(plan.frames, 50)).astype(int).tolist())
                   for key in plan.images}
        accs = {key: fmt.StatsAccumulator(image=True) for key in plan.images}
        for message in read_recording(info.mcap, topics=set(wanted)):
            seen[message.topic] += 1
            m = seen[message.topic]
            for key in wanted[message.topic]:
                picks = plan.images[key][1]
                pixels = None
                while cursor[key] < plan.frames and picks[cursor[key]] == m:
                    if pixels is None:
                        pixels = _rgb(key, message.topic, message.value)
                        video = self._video(key, pixels, info.episode)
                        starts.setdefault(key, video.frames)
                    if cursor[key] in samples[key]:
                        accs[key].add(pixels)
                    self.videos[key].add(pixels)
                    cursor[key] += 1
        columns: dict[str, Any] = {}
        for key in plan.images:
            if cursor[key] != plan.frames:
                raise ConfigError(f"feature {key!r}: episode {info.episode} gave {cursor[key]} of its "
                                  f"{plan.frames} camera frames (the file changed while exporting?)")
            stats[key] = accs[key].finish(plan.frames)
            chunk, file = self.video_files[key]
            start = starts[key]
            columns.update({f"videos/{key}/chunk_index": chunk, f"videos/{key}/file_index": file,
                            f"videos/{key}/from_timestamp": start / self.fps,
                            f"videos/{key}/to_timestamp": (start + plan.frames) / self.fps})
        return columns

    def _video(self, key: str, pixels: npt.NDArray[np.uint8], episode: int) -> _VideoFile:
        """The video that episode ``episode``'s frames of ``key`` go into (a new file past the size limit)."""
        height, width = pixels.shape[:2]
        self._declare(key, {"dtype": "video", "shape": [height, width, 3], "names": ["height", "width", "channels"]},
                      episode)
        video = self.videos.get(key)
        if video is not None and key not in self.checked:
            self.checked.add(key)
            if video.path.stat().st_size >= fmt.VIDEO_FILE_MB * 2**20:
                video.close()
                self.video_files[key] = fmt.next_file(*self.video_files[key])
                video = None
        if video is None:
            chunk, file = self.video_files.setdefault(key, (0, 0))
            video = _VideoFile(self.root / fmt.video_path(key, chunk, file), self.fps, width, height, self.vcodec,
                               self.crf, self.gop)
            self.videos[key] = video
        self.checked.add(key)
        return video
