"""``agentsctl episodes list | export-lerobot``: recorded episodes (agents_core.episodes) and their LeRobot export."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from ..errors import ConfigError
from .connection import one_line_errors
from .output import print_json, print_table, say
from .topics import JsonOpt

if TYPE_CHECKING:
    from ..episodes import LeRobotFeature

__all__ = ["app"]

app = typer.Typer(help="List recorded episodes; export them as a LeRobot dataset.", no_args_is_help=True)


@app.command("list")
@one_line_errors
def list_episodes(directory: Annotated[Path, typer.Argument(help="the episodes folder (episode_*.mcap, .json)")],
                  json_out: JsonOpt = False) -> None:
    """The episodes a folder holds: number, task, outcome, how it ended, values, size, topics."""
    from ..episodes import load_episodes  # noqa: PLC0415 - the record extra only here

    infos = load_episodes(directory)
    if json_out:
        print_json([info.to_json() for info in infos])
        return
    columns = ["episode", "task", "success", "ended", "seconds", "values", "MiB", "topics"]
    print_table(f"episodes in {directory}", columns,
                [[str(i.episode), i.task, str(i.success), i.ended + (f" ({i.reason})" if i.reason else ""),
                  f"{i.duration_s:.1f}", str(i.messages), f"{i.bytes / 2**20:.1f}", ", ".join(sorted(i.topics))]
                 for i in infos])


def _features(pairs: list[str]) -> dict[str, str | LeRobotFeature]:
    from ..episodes import LeRobotFeature  # noqa: PLC0415

    features: dict[str, str | LeRobotFeature] = {}
    for pair in pairs:
        key, sep, source = pair.partition("=")
        if not sep or not key or not source:
            raise ConfigError(f"--feature {pair!r}: write FEATURE=TOPIC (e.g. observation.state=joint_states), "
                              "or FEATURE=TOPIC:FIELD (e.g. observation.velocity=joint_states:velocity)")
        topic, _, field = source.partition(":")
        features[key] = LeRobotFeature(topic.lstrip("/"), field or None)
    return features


@app.command("export-lerobot")
@one_line_errors
def export_lerobot(directory: Annotated[Path, typer.Argument(help="the episodes folder")],
                   output: Annotated[Path, typer.Argument(help="the dataset folder to write")],
                   repo_id: Annotated[str, typer.Option("--repo-id", help="the dataset's name, user/name")],
                   fps: Annotated[int, typer.Option("--fps", help="frames per second", min=1, max=10_000)],
                   feature: Annotated[list[str], typer.Option(
                       "--feature", "-f", help="FEATURE=TOPIC[:FIELD], e.g. observation.state=joint_states, "
                                               "observation.images.top=camera, action=commands (repeatable)")],
                   frame_topic: Annotated[str | None, typer.Option(
                       "--frame-topic", help="one frame per message of this topic (default: every 1/fps s)")] = None,
                   episode: Annotated[list[int] | None, typer.Option(
                       "--episode", "-e", help="only these episode numbers (repeatable)")] = None,
                   robot_type: Annotated[str | None, typer.Option("--robot-type", help="robot_type in info")] = None,
                   vcodec: Annotated[str, typer.Option("--vcodec", help="libx264 or libsvtav1")] = "libx264",
                   overwrite: Annotated[bool, typer.Option("--overwrite", help="replace OUTPUT if it exists")] = False,
                   json_out: JsonOpt = False) -> None:
    """Export recorded episodes as a LeRobotDataset v3.0 folder (needs the 'dataset' extra)."""
    from ..episodes import export_lerobot_dataset, load_episodes  # noqa: PLC0415 - the dataset extra only here

    infos = load_episodes(directory)
    if episode:
        missing = sorted(set(episode) - {i.episode for i in infos})
        if missing:
            raise ConfigError(f"{directory} has no episode {missing}")
        infos = [i for i in infos if i.episode in set(episode)]
    summary = export_lerobot_dataset(infos, output, repo_id=repo_id, fps=fps, features=_features(feature),
                                     frame_topic=frame_topic.lstrip("/") if frame_topic else None,
                                     robot_type=robot_type, vcodec=vcodec, overwrite=overwrite)
    if json_out:
        print_json({"root": str(summary.root), "episodes": summary.episodes, "frames": summary.frames,
                    "seconds": round(summary.seconds, 3), "skipped": summary.skipped})
        return
    say(f"wrote {summary.episodes} episode(s), {summary.frames} frames to {summary.root} in {summary.seconds:.1f} s")
    for number, why in summary.skipped.items():
        say(f"  skipped episode {number}: {why}")
