"""Hand-written evaluation output directories in the format of docs/evaluate.md (evaluation.json, results.jsonl,
frames/), for the report, compare and expect tests; and a tiny PNG writer (no imaging library needed)."""

from __future__ import annotations

import json
import math
import struct
import zlib
from collections.abc import Sequence
from pathlib import Path
from typing import Any


def png(width: int, height: int, pixel: Any) -> bytes:
    """An RGB PNG whose pixel (x, y) is ``pixel(x, y) -> (r, g, b)``."""
    rows = b"".join(b"\x00" + bytes(c for x in range(width) for c in pixel(x, y)) for y in range(height))

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    header = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", zlib.compress(rows, 9)) + \
        chunk(b"IEND", b"")


def frame_png(step: int, total: int, success: bool) -> bytes:
    """A 96x72 thumbnail: a target square and a dot moving towards it (closer each frame when ``success``)."""
    progress = step / max(1, total - 1)
    reach = progress if success else 0.45 * progress
    dot_x, dot_y = 10 + reach * 66, 60 - reach * 44

    def pixel(x: int, y: int) -> tuple[int, int, int]:
        if 70 <= x <= 82 and 10 <= y <= 22:
            return (40, 160, 70)
        if (x - dot_x) ** 2 + (y - dot_y) ** 2 <= 25:
            return (200, 60, 40)
        shade = 225 + (y * 20) // 72
        return (shade, shade, min(255, shade + 8))

    return png(96, 72, pixel)


def info(name: str = "reacher-expert", episodes: int = 4, seeds: Sequence[int] | None = None,
         **fields: Any) -> dict[str, Any]:
    """An evaluation.json document; ``fields`` override any key."""
    doc: dict[str, Any] = {
        "name": name, "world": "Reacher-v5", "recipe": "examples/reacher_expert.py", "transport": "memory",
        "clock": "lockstep", "episodes": episodes, "seeds": list(seeds if seeds is not None else range(episodes)),
        "success_rule": "fingertip within 2 cm of the target at the end",
        "limits": {"max_steps": 50, "max_wall_s": 60.0}, "started": "2026-12-01T21:00:00+00:00",
        "finished": "2026-12-01T21:01:00+00:00", "interrupted": False, "agents_core_version": "0.7.0"}
    doc.update(fields)
    return doc


def episode(index: int, success: bool, *, seed: int | None = None, steps: int = 50, frames: Sequence[str] = (),
            **fields: Any) -> dict[str, Any]:
    """A results.jsonl line; rewards climb towards 0 (Reacher's rewards are negative distances)."""
    rewards = [-(1.0 - (i + 1) / steps) * (0.2 if success else 0.6) - 0.01 * (index % 3) for i in range(steps)]
    doc: dict[str, Any] = {
        "episode": index, "seed": index if seed is None else seed, "success": success,
        "reward_sum": math.fsum(rewards), "steps": steps,
        "time_to_success_s": round(0.02 * (30 + 3 * index), 6) if success else None,
        "steps_to_success": 30 + 3 * index if success else None, "wall_s": 0.4 + 0.01 * index,
        "ended": "success" if success else "step_limit", "reason": None, "rewards": rewards, "frames": list(frames)}
    doc.update(fields)
    return doc


def write_dir(out: Path, evaluation: dict[str, Any] | None, lines: Sequence[dict[str, Any] | str | bytes],
              *, newline_at_end: bool = True) -> Path:
    """Write ``out/evaluation.json`` and ``out/results.jsonl`` (dicts as JSON lines, str/bytes as they are)."""
    out.mkdir(parents=True, exist_ok=True)
    if evaluation is not None:
        (out / "evaluation.json").write_text(json.dumps(evaluation), encoding="utf-8")
    chunks = [line if isinstance(line, bytes) else
              (line if isinstance(line, str) else json.dumps(line)).encode("utf-8") for line in lines]
    data = b"\n".join(chunks) + (b"\n" if chunks and newline_at_end else b"")
    (out / "results.jsonl").write_bytes(data)
    return out


def make_run(out: Path, outcomes: Sequence[bool], *, name: str = "reacher-expert", frames: bool = True,
             seeds: Sequence[int] | None = None, **info_fields: Any) -> Path:
    """A complete evaluation with one episode per outcome; frames (4 per episode) for the first of each outcome."""
    lines = []
    framed: set[bool] = set()
    seeds = list(seeds) if seeds is not None else list(range(len(outcomes)))
    for i, success in enumerate(outcomes):
        names: list[str] = []
        if frames and success not in framed:
            framed.add(success)
            (out / "frames").mkdir(parents=True, exist_ok=True)
            for k in range(4):
                rel = f"frames/ep{i:04d}_{k:02d}.png"
                (out / rel).write_bytes(frame_png(k, 4, success))
                names.append(rel)
        lines.append(episode(i, success, seed=seeds[i], frames=names))
    return write_dir(out, info(name=name, episodes=len(outcomes), seeds=seeds, **info_fields), lines)
