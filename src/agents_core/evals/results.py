"""Reading an evaluation's output directory back: ``evaluation.json`` and ``results.jsonl``, as dataclasses.

The files may come from anywhere (a colleague's run, a CI artifact), so reading them is bounded:
each line of ``results.jsonl`` is read with a length cap (a line without a newline is never read
whole), the number of lines and the total size are capped, every line is decoded by
:func:`agents_core.support.bounded_json.loads` and every field is checked. A bad line is an error that names
the file, the line and the field. The one exception is the last line when it has no newline and does
not decode: the run was interrupted while writing it, so it is dropped and
:attr:`EvaluationResults.partial_last_line` says so.

Frame paths are checked too (:meth:`EvaluationResults.frame_file`): a results line may name only
files inside its own directory, so a report never embeds ``/etc/passwd`` or a symlink out of it.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..errors import ConfigError
from ..support.bounded_json import InvalidJsonError, JsonLimits, loads

__all__ = [
    "ENDED_VALUES",
    "EVALUATION_FILE",
    "RESULTS_FILE",
    "EpisodeResult",
    "EvaluationInfo",
    "EvaluationResults",
    "ResultsError",
    "ResultsLimits",
    "load_results",
    "read_capped",
]

#: The run's description, written when it starts and again when it ends.
EVALUATION_FILE = "evaluation.json"
#: One JSON object per finished episode, one per line.
RESULTS_FILE = "results.jsonl"
#: Why an episode ended, as the runner writes it (other short words are accepted and shown as they are).
ENDED_VALUES = ("success", "terminated", "truncated", "step_limit", "time_limit", "error", "world_died",
                "interrupted")

_MIB = 1024 * 1024
_MAX_ENDED_LEN = 64


class ResultsError(ConfigError):
    """An evaluation's output directory cannot be read: a file is missing, too large, or a line is bad."""


@dataclass(frozen=True)
class ResultsLimits:
    """What reading one results directory may cost; :func:`load_results` refuses more.

    - ``max_line_bytes``: one line of ``results.jsonl`` (an episode of 100,000 steps writes ~2 MiB of rewards).
    - ``max_lines``: the lines of ``results.jsonl`` (episodes).
    - ``max_total_bytes``: the whole of ``results.jsonl``.
    - ``max_info_bytes``: ``evaluation.json``.
    - ``max_frame_bytes``: one thumbnail a report embeds (larger ones are shown as missing).
    """

    max_line_bytes: int = 8 * _MIB
    max_lines: int = 100_000
    max_total_bytes: int = 256 * _MIB
    max_info_bytes: int = 4 * _MIB
    max_frame_bytes: int = 2 * _MIB


@dataclass(frozen=True)
class EvaluationInfo:
    """``evaluation.json``: what was evaluated, how, and whether the run finished."""

    name: str
    world: str
    recipe: str
    transport: str
    clock: str
    episodes: int
    seeds: tuple[int, ...]
    success_rule: str
    max_steps: int | None
    max_wall_s: float | None
    started: str
    finished: str | None
    interrupted: bool
    agents_core_version: str


@dataclass(frozen=True)
class EpisodeResult:
    """One line of ``results.jsonl``: one finished episode."""

    episode: int
    seed: int
    success: bool
    reward_sum: float
    steps: int
    time_to_success_s: float | None
    steps_to_success: int | None
    wall_s: float
    ended: str
    reason: str | None
    rewards: tuple[float, ...] = ()
    frames: tuple[str, ...] = ()


@dataclass(frozen=True)
class EvaluationResults:
    """An evaluation read back: its :class:`EvaluationInfo` and its episodes, in episode order."""

    out_dir: Path
    info: EvaluationInfo
    episodes: tuple[EpisodeResult, ...]
    #: The last line was cut short (no newline, not JSON): the run stopped while writing it; it was dropped.
    partial_last_line: bool = False
    limits: ResultsLimits = field(default_factory=ResultsLimits)

    @property
    def n(self) -> int:
        """How many episodes finished."""
        return len(self.episodes)

    @property
    def successes(self) -> int:
        """How many of them succeeded."""
        return sum(1 for e in self.episodes if e.success)

    @property
    def success_rate(self) -> float:
        """``successes / n`` (0.0 when no episode finished)."""
        return self.successes / self.n if self.n else 0.0

    @property
    def failed_seeds(self) -> tuple[int, ...]:
        """The seeds of the episodes that did not succeed, in episode order."""
        return tuple(e.seed for e in self.episodes if not e.success)

    @property
    def complete(self) -> bool:
        """Whether the run finished every episode it was asked for, uninterrupted."""
        return not self.info.interrupted and self.info.finished is not None and self.n >= self.info.episodes

    def frame_file(self, relative: str) -> Path | None:
        """The file a ``frames`` entry names, if it is a regular file inside :attr:`out_dir` (links resolved)."""
        if not relative or "\x00" in relative or Path(relative).is_absolute():
            return None
        root = self.out_dir.resolve()
        try:
            path = (root / relative).resolve()
        except (OSError, RuntimeError):  # a link loop
            return None
        if not path.is_relative_to(root) or not path.is_file():
            return None
        return path


def load_results(out_dir: str | Path, limits: ResultsLimits | None = None) -> EvaluationResults:
    """Read the evaluation in ``out_dir`` (``evaluation.json`` and ``results.jsonl``), bounded by ``limits``.

    Raises :class:`ResultsError` naming the file (and line, and field) for a missing file, one over a
    limit, a line that is not JSON or a field of the wrong type, and for two lines of one episode.
    A ``results.jsonl`` that does not exist yet (no episode finished) reads as no episodes.
    """
    limits = limits or ResultsLimits()
    root = Path(out_dir)
    if not root.is_dir():
        raise ResultsError(f"{root} is not a directory (an evaluation's output directory holds {EVALUATION_FILE} "
                           f"and {RESULTS_FILE})")
    info = _read_info(root / EVALUATION_FILE, limits)
    episodes, partial = _read_episodes(root / RESULTS_FILE, limits)
    return EvaluationResults(out_dir=root, info=info, episodes=episodes, partial_last_line=partial, limits=limits)


def read_capped(path: Path, cap: int) -> bytes:
    """The bytes of the file ``path``, or :class:`ResultsError` naming the limit if there are more than ``cap``.

    The file's size is looked at first: ``read(cap + 1)`` alone would allocate ``cap`` bytes even for a small file.
    """
    with path.open("rb") as stream:
        size = os.fstat(stream.fileno()).st_size
        if size > cap:
            raise ResultsError(f"{path} has {size} bytes, more than {cap}")
        data = stream.read(size + 1)  # the file may have grown since
    if len(data) > cap:
        raise ResultsError(f"{path} has more than {cap} bytes")
    return data


def _read_info(path: Path, limits: ResultsLimits) -> EvaluationInfo:
    try:
        data = read_capped(path, limits.max_info_bytes)
    except ResultsError as exc:
        raise ResultsError(f"{exc} (ResultsLimits.max_info_bytes)") from None
    except FileNotFoundError:
        raise ResultsError(f"{path} does not exist: {path.parent} is not an evaluation's output "
                           "directory") from None
    except OSError as exc:
        raise ResultsError(f"{path} cannot be read: {exc}") from None
    try:
        doc = loads(data, JsonLimits(max_bytes=limits.max_info_bytes, max_array_len=limits.max_lines * 10))
    except InvalidJsonError as exc:
        raise ResultsError(f"{path}: {exc}") from None
    if not isinstance(doc, dict):
        raise ResultsError(f"{path}: expected a JSON object, got {type(doc).__name__}")
    where = str(path)
    raw_limits = doc.get("limits") or {}
    if not isinstance(raw_limits, dict):
        raise ResultsError(f"{where}: field 'limits' must be an object, got {type(raw_limits).__name__}")
    seeds = _field(doc, "seeds", list, where, default=[])
    for i, seed in enumerate(seeds):
        _check_int(seed, f"seeds[{i}]", where)
    return EvaluationInfo(
        name=_field(doc, "name", str, where),
        world=_field(doc, "world", str, where, default=""),
        recipe=_field(doc, "recipe", str, where, default=""),
        transport=_field(doc, "transport", str, where, default=""),
        clock=_field(doc, "clock", str, where, default=""),
        episodes=_check_int(doc.get("episodes", len(seeds)), "episodes", where),
        seeds=tuple(seeds),
        success_rule=_field(doc, "success_rule", str, where, default=""),
        max_steps=_optional_int(raw_limits.get("max_steps"), "limits.max_steps", where),
        max_wall_s=_optional_float(raw_limits.get("max_wall_s"), "limits.max_wall_s", where),
        started=_field(doc, "started", str, where, default=""),
        finished=_field(doc, "finished", str, where, default=None, optional=True),
        interrupted=_field(doc, "interrupted", bool, where, default=False),
        agents_core_version=_field(doc, "agents_core_version", str, where, default=""),
    )


def _read_episodes(path: Path, limits: ResultsLimits) -> tuple[tuple[EpisodeResult, ...], bool]:
    try:
        stream = path.open("rb")
    except FileNotFoundError:
        return (), False
    except OSError as exc:
        raise ResultsError(f"{path} cannot be read: {exc}") from None
    line_limits = JsonLimits(max_bytes=limits.max_line_bytes, max_array_len=limits.max_line_bytes,
                             max_str_len=limits.max_line_bytes, allow_non_finite=True)
    episodes: list[EpisodeResult] = []
    seen: dict[int, int] = {}
    total = 0
    partial = False
    with stream:
        number = 0
        while True:
            raw = stream.readline(limits.max_line_bytes + 1)
            if not raw:
                break
            number += 1
            where = f"{path}, line {number}"
            total += len(raw)
            if total > limits.max_total_bytes:
                raise ResultsError(f"{path} is larger than {limits.max_total_bytes} bytes "
                                   "(ResultsLimits.max_total_bytes)")
            if number > limits.max_lines:
                raise ResultsError(f"{path} has more than {limits.max_lines} lines (ResultsLimits.max_lines)")
            ends = raw.endswith(b"\n")
            if not ends and len(raw) > limits.max_line_bytes:
                raise ResultsError(f"{where} is longer than {limits.max_line_bytes} bytes "
                                   "(ResultsLimits.max_line_bytes)")
            if not raw.strip():
                continue
            try:
                doc = loads(raw, line_limits)
            except InvalidJsonError as exc:
                if not ends and not stream.read(1):
                    partial = True  # the run stopped while writing its last line
                    break
                raise ResultsError(f"{where}: {exc}") from None
            episode = _episode(doc, where)
            if episode.episode in seen:
                raise ResultsError(f"{where}: episode {episode.episode} is already on line {seen[episode.episode]}")
            seen[episode.episode] = number
            episodes.append(episode)
    episodes.sort(key=lambda e: e.episode)
    return tuple(episodes), partial


def _episode(doc: Any, where: str) -> EpisodeResult:
    if not isinstance(doc, dict):
        raise ResultsError(f"{where}: expected a JSON object, got {type(doc).__name__}")
    # Checked in the order the fields are written, so the first error is the first bad field.
    index = _check_int(_field(doc, "episode", int, where), "episode", where, minimum=0)
    seed = _check_int(_field(doc, "seed", int, where), "seed", where)
    success = _field(doc, "success", bool, where)
    rewards = _field(doc, "rewards", list, where, default=[])
    for i, value in enumerate(rewards):
        _check_float(value, f"rewards[{i}]", where)
    # Without a reward_sum, the rewards' plain sum (math.fsum raises on overflow and on inf + -inf).
    reward_sum = _check_float(doc["reward_sum"], "reward_sum", where) if "reward_sum" in doc else \
        sum(float(r) for r in rewards)
    steps = _check_int(_field(doc, "steps", int, where), "steps", where, minimum=0)
    time_to_success = _optional_float(doc.get("time_to_success_s"), "time_to_success_s", where)
    steps_to_success = _optional_int(doc.get("steps_to_success"), "steps_to_success", where)
    wall_s = _check_float(doc.get("wall_s", 0.0), "wall_s", where)
    ended = _field(doc, "ended", str, where)
    if not ended or len(ended) > _MAX_ENDED_LEN:
        raise ResultsError(f"{where}: field 'ended' must be a word such as {', '.join(ENDED_VALUES)}; got "
                           f"{ended[:_MAX_ENDED_LEN]!r}")
    reason = _field(doc, "reason", str, where, default=None, optional=True)
    frames = _field(doc, "frames", list, where, default=[])
    for i, value in enumerate(frames):
        if not isinstance(value, str):
            raise ResultsError(f"{where}: field 'frames[{i}]' must be a string (a path relative to the output "
                               f"directory), got {type(value).__name__}")
    return EpisodeResult(episode=index, seed=seed, success=success, reward_sum=reward_sum, steps=steps,
                         time_to_success_s=time_to_success, steps_to_success=steps_to_success, wall_s=wall_s,
                         ended=ended, reason=reason, rewards=tuple(float(r) for r in rewards), frames=tuple(frames))


_MISSING = object()


def _field(doc: Mapping[str, Any], name: str, kind: type, where: str, *, default: Any = _MISSING,
           optional: bool = False) -> Any:
    """``doc[name]``, which must be a ``kind`` (or None if ``optional``); ``default`` when absent, if given."""
    if name not in doc:
        if default is _MISSING:
            raise ResultsError(f"{where}: field {name!r} is missing")
        return default
    value = doc[name]
    if value is None and optional:
        return None
    # bool is an int in Python, not in the file's meaning.
    if not isinstance(value, kind) or (kind is int and isinstance(value, bool)):
        expected = {str: "a string", int: "an integer", bool: "true or false", list: "a list"}.get(kind, kind.__name__)
        raise ResultsError(f"{where}: field {name!r} must be {expected}{' or null' if optional else ''}, got "
                           f"{_kind(value)}")
    return value


def _kind(value: Any) -> str:
    return "null" if value is None else type(value).__name__


def _check_int(value: Any, name: str, where: str, *, minimum: int | None = None) -> int:
    if isinstance(value, bool) or not isinstance(value, int):
        raise ResultsError(f"{where}: field {name!r} must be an integer, got {_kind(value)}")
    if minimum is not None and value < minimum:
        raise ResultsError(f"{where}: field {name!r} must be >= {minimum}, got {value}")
    return value


def _check_float(value: Any, name: str, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ResultsError(f"{where}: field {name!r} must be a number, got {_kind(value)}")
    return float(value)


def _optional_int(value: Any, name: str, where: str) -> int | None:
    return None if value is None else _check_int(value, name, where)


def _optional_float(value: Any, name: str, where: str) -> float | None:
    return None if value is None else _check_float(value, name, where)
