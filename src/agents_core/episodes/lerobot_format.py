"""The files of a LeRobotDataset v3.0 folder, written with pyarrow alone (no LeRobot, no torch, no pandas).

The layout (as LeRobot 0.4's ``lerobot.datasets.utils`` reads it)::

    meta/info.json                          codebase_version "v3.0", fps, totals, paths, features
    meta/stats.json                         per feature: min, max, mean, std, count, q01 .. q99
    meta/tasks.parquet                      one row per task: the task text is the (pandas) index, task_index
    meta/episodes/chunk-000/file-000.parquet  one row per episode: length, tasks, where its rows and video are
    data/chunk-000/file-000.parquet         one row per frame: the vector features, timestamp, the indices
    videos/<key>/chunk-000/file-000.mp4     each camera's frames, episodes one after another

Vector features are ``float32`` fixed-size lists; camera features have dtype ``video`` and live only in
the mp4 files, the episode row saying from which second to which of the file an episode runs.
Image statistics are per channel, in [0, 1], shaped (3, 1, 1) as LeRobot computes them.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from ..errors import ConfigError
from ..support.lazy_numpy import np, npt

__all__ = ["CODEBASE_VERSION", "DEFAULT_FEATURES", "QUANTILES", "StatsAccumulator", "data_path", "info_document",
           "require_pyarrow", "video_path", "write_episodes_table", "write_json", "write_tasks"]

CODEBASE_VERSION = "v3.0"
CHUNKS_SIZE = 1000
DATA_FILE_MB = 100
VIDEO_FILE_MB = 200
DATA_PATH = "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet"
VIDEO_PATH = "videos/{video_key}/chunk-{chunk_index:03d}/file-{file_index:03d}.mp4"
EPISODES_PATH = "meta/episodes/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet"
#: The columns every frame has besides the features.
DEFAULT_FEATURES: dict[str, dict[str, Any]] = {
    "timestamp": {"dtype": "float32", "shape": [1], "names": None},
    "frame_index": {"dtype": "int64", "shape": [1], "names": None},
    "episode_index": {"dtype": "int64", "shape": [1], "names": None},
    "index": {"dtype": "int64", "shape": [1], "names": None},
    "task_index": {"dtype": "int64", "shape": [1], "names": None},
}
QUANTILES = (0.01, 0.10, 0.50, 0.90, 0.99)


def require_pyarrow() -> Any:
    """The ``pyarrow`` module, or ConfigError naming the extra."""
    try:
        import pyarrow  # noqa: PLC0415 - the 'dataset' extra
        import pyarrow.parquet  # noqa: PLC0415
    except ImportError as exc:
        raise ConfigError(f"exporting a LeRobot dataset needs the 'dataset' extra ({exc}); "
                          "pip install 'agents-core[dataset]'") from None
    return pyarrow


def data_path(chunk: int, file: int) -> str:
    """The data file of chunk ``chunk``, file ``file`` (relative to the dataset's root)."""
    return DATA_PATH.format(chunk_index=chunk, file_index=file)


def video_path(key: str, chunk: int, file: int) -> str:
    """The video file of camera ``key``, chunk ``chunk``, file ``file`` (relative to the dataset's root)."""
    return VIDEO_PATH.format(video_key=key, chunk_index=chunk, file_index=file)


def next_file(chunk: int, file: int) -> tuple[int, int]:
    """The (chunk, file) after ``(chunk, file)``: files 0 .. CHUNKS_SIZE - 1 in each chunk."""
    return (chunk + 1, 0) if file == CHUNKS_SIZE - 1 else (chunk, file + 1)


def write_json(path: Path, document: Mapping[str, Any]) -> None:
    """``document`` as indented JSON at ``path`` (folders made)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(document, indent=4, ensure_ascii=False), encoding="utf-8")


def info_document(*, fps: int, features: Mapping[str, Mapping[str, Any]], total_episodes: int, total_frames: int,
                  total_tasks: int, robot_type: str | None, has_video: bool) -> dict[str, Any]:
    """``meta/info.json``."""
    return {"codebase_version": CODEBASE_VERSION, "robot_type": robot_type, "total_episodes": total_episodes,
            "total_frames": total_frames, "total_tasks": total_tasks, "chunks_size": CHUNKS_SIZE,
            "data_files_size_in_mb": DATA_FILE_MB, "video_files_size_in_mb": VIDEO_FILE_MB, "fps": fps,
            "splits": {"train": f"0:{total_episodes}"}, "data_path": DATA_PATH,
            "video_path": VIDEO_PATH if has_video else None, "features": {**features, **DEFAULT_FEATURES}}


def _pandas_metadata() -> bytes:
    """The ``pandas`` schema metadata of the tasks table: ``pandas.read_parquet`` makes the task text its index."""
    columns = [{"name": "task_index", "field_name": "task_index", "pandas_type": "int64", "numpy_type": "int64",
                "metadata": None},
               {"name": None, "field_name": "__index_level_0__", "pandas_type": "unicode", "numpy_type": "object",
                "metadata": None}]
    return json.dumps({"index_columns": ["__index_level_0__"], "column_indexes": [], "columns": columns,
                       "attributes": {}, "creator": {"library": "agents_core"}, "pandas_version": "2.0.0"}).encode()


def write_tasks(root: Path, tasks: Sequence[str]) -> None:
    """``meta/tasks.parquet``: the tasks in order (task_index = position), the text as the pandas index."""
    pa = require_pyarrow()
    table = pa.table({"task_index": pa.array(range(len(tasks)), pa.int64()),
                      "__index_level_0__": pa.array(list(tasks), pa.string())})
    table = table.replace_schema_metadata({b"pandas": _pandas_metadata()})
    path = root / "meta" / "tasks.parquet"
    path.parent.mkdir(parents=True, exist_ok=True)
    pa.parquet.write_table(table, path)


def write_episodes_table(root: Path, rows: Sequence[Mapping[str, Any]]) -> None:
    """``meta/episodes/chunk-000/file-000.parquet``: one row per episode (columns as LeRobot names them)."""
    pa = require_pyarrow()
    columns: dict[str, list[Any]] = {}
    for row in rows:
        for name in row:
            columns.setdefault(name, [])
    for row in rows:
        for name, values in columns.items():
            values.append(row.get(name))
    arrays = {}
    for name, values in columns.items():
        if name == "tasks":
            arrays[name] = pa.array(values, pa.list_(pa.string()))
        elif name.endswith("/count"):
            arrays[name] = pa.array([[int(np.asarray(v).ravel()[0])] for v in values], pa.list_(pa.int64()))
        elif name.startswith("stats/"):  # flattened: LeRobot leaves these columns out when it loads
            arrays[name] = pa.array([np.asarray(v, np.float64).ravel().tolist() for v in values],
                                    pa.list_(pa.float64()))
        elif name.endswith("_timestamp"):
            arrays[name] = pa.array(values, pa.float64())
        else:
            arrays[name] = pa.array(values, pa.int64())
    path = root / EPISODES_PATH.format(chunk_index=0, file_index=0)
    path.parent.mkdir(parents=True, exist_ok=True)
    pa.parquet.write_table(pa.table(arrays), path)


class StatsAccumulator:
    """Statistics of one feature over an episode or a dataset: min, max, mean, std, count, quantiles.

    Vectors: give each frame's values (``add``); the episode's quantiles are exact. Images: give each
    sampled frame as HxWx3 uint8 (``add_image``), reduced per channel to [0, 1] (LeRobot's shape
    (3, 1, 1)). :meth:`merge` combines episodes as LeRobot's ``aggregate_stats`` does (weighted
    means and variances, count-weighted quantiles).
    """

    def __init__(self, image: bool = False) -> None:
        self.image = image
        self._rows: list[npt.NDArray[np.float64]] = []
        self.stats: dict[str, npt.NDArray[Any]] | None = None

    def add(self, values: npt.NDArray[Any]) -> None:
        """One frame's values (a vector) or, for images, one sampled frame (HxWxC, 0..255)."""
        if self.image:
            pixels = np.asarray(values, np.float64)[::4, ::4].reshape(-1, values.shape[-1]) / 255.0
            self._rows.append(pixels)
        else:
            self._rows.append(np.asarray(values, np.float64).reshape(1, -1))

    @classmethod
    def of_column(cls, values: npt.NDArray[Any]) -> dict[str, npt.NDArray[Any]]:
        """The statistics of a whole column at once (one row per frame)."""
        acc = cls()
        acc.add_rows(np.asarray(values, np.float64).reshape(len(values), -1))
        return acc.finish(len(values))

    def add_rows(self, rows: npt.NDArray[Any]) -> None:
        """Several frames' values at once (one row each)."""
        self._rows.append(np.asarray(rows, np.float64))

    def finish(self, count: int) -> dict[str, npt.NDArray[Any]]:
        """The statistics of what was added (``count``: the frames they stand for)."""
        data = np.concatenate(self._rows, axis=0) if self._rows else np.zeros((1, 1))
        self._rows = []
        stats: dict[str, npt.NDArray[Any]] = {
            "min": data.min(axis=0), "max": data.max(axis=0), "mean": data.mean(axis=0), "std": data.std(axis=0)}
        for q in QUANTILES:
            stats[f"q{round(q * 100):02d}"] = np.quantile(data, q, axis=0)
        if self.image:
            stats = {k: v.reshape(-1, 1, 1) for k, v in stats.items()}
        stats["count"] = np.array([count], np.int64)
        self.stats = stats
        return stats

    @staticmethod
    def merge(episodes: Sequence[Mapping[str, npt.NDArray[Any]]]) -> dict[str, npt.NDArray[Any]]:
        """Dataset statistics from per-episode ones."""
        counts = np.array([float(e["count"][0]) for e in episodes])
        weights = counts / counts.sum()
        means = np.stack([e["mean"] for e in episodes])
        shape = (-1,) + (1,) * (means.ndim - 1)
        mean = (weights.reshape(shape) * means).sum(axis=0)
        variances = np.stack([e["std"] ** 2 for e in episodes])
        var = (weights.reshape(shape) * (variances + (means - mean) ** 2)).sum(axis=0)
        merged: dict[str, npt.NDArray[Any]] = {
            "min": np.min(np.stack([e["min"] for e in episodes]), axis=0),
            "max": np.max(np.stack([e["max"] for e in episodes]), axis=0),
            "mean": mean, "std": np.sqrt(var), "count": np.array([int(counts.sum())], np.int64)}
        for q in QUANTILES:
            key = f"q{round(q * 100):02d}"
            merged[key] = (weights.reshape(shape) * np.stack([e[key] for e in episodes])).sum(axis=0)
        return merged


def stats_json(stats: Mapping[str, Mapping[str, npt.NDArray[Any]]]) -> dict[str, dict[str, Any]]:
    """``meta/stats.json``'s document: every array as (nested) lists."""
    return {key: {name: np.asarray(value).tolist() for name, value in feature.items()}
            for key, feature in stats.items()}
