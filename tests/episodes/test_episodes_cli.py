"""``agentsctl episodes list`` and ``agentsctl episodes export-lerobot`` on recorded episodes."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

pytest.importorskip("typer", reason="pip install 'agents-core[cli]'")
pytest.importorskip("mcap", reason="pip install 'agents-core[record]'")

from typer.testing import CliRunner

from agents_core.cli.app import app

from .dataset_parts import FPS, record_episodes


@pytest.fixture(scope="module")
def episodes(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return record_episodes(tmp_path_factory.mktemp("episodes"), episodes=3, steps=6).directory


def test_list_shows_each_episode(episodes: Path) -> None:
    result = CliRunner().invoke(app, ["episodes", "list", str(episodes), "--json"])
    assert result.exit_code == 0, result.output
    rows = json.loads(result.output)
    assert [r["episode"] for r in rows] == [0, 1, 2] and rows[0]["task"] == "reach the target"
    table = CliRunner().invoke(app, ["episodes", "list", str(episodes)])
    assert table.exit_code == 0 and "reach the target" in table.output and "stopped" in table.output


def test_export_lerobot_writes_the_dataset(episodes: Path, tmp_path: Path) -> None:
    pytest.importorskip("pyarrow", reason="pip install 'agents-core[dataset]'")
    pytest.importorskip("av", reason="pip install 'agents-core[dataset]'")
    out = tmp_path / "ds"
    args = ["episodes", "export-lerobot", str(episodes), str(out), "--repo-id", "agents/cli", "--fps", str(FPS),
            "-f", "observation.state=joints", "-f", "observation.images.top=top", "-f", "action=/command",
            "--frame-topic", "joints", "--episode", "0", "--episode", "2", "--json"]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 0, result.output
    assert json.loads(result.output)["episodes"] == 2
    info = json.loads((out / "meta/info.json").read_text())
    assert info["total_episodes"] == 2 and info["total_frames"] == 6 + 8
    again = CliRunner().invoke(app, args)
    assert again.exit_code == 1 and "exists; pass overwrite=True (--overwrite)" in again.output
    bad = CliRunner().invoke(app, [*args[:8], "-f", "action", "--overwrite"])
    assert bad.exit_code == 1 and "write FEATURE=TOPIC" in bad.output
    missing = CliRunner().invoke(app, [*args, "--episode", "7", "--overwrite"])
    assert missing.exit_code == 1 and "has no episode [7]" in missing.output
