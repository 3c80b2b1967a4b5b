"""The vision demo (``nox -s demo -- vision --model PATH --images DIR``) on ../shared's model and photos."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from .vision_recipe import SHARED_IMAGES, needs_ssd

pytestmark = pytest.mark.local_models


def test_vision_demo_prints_a_table_and_writes_annotated_images(tmp_path: Path) -> None:
    model = needs_ssd()
    result = subprocess.run([sys.executable, "-m", "agents_core.demo", "vision", "--model", model, "--images",
                             str(SHARED_IMAGES), "--out", str(tmp_path)], capture_output=True, text=True, timeout=180,
                            check=False)
    assert result.returncode == 0, result.stderr[-3000:]
    rows = [line.split() for line in result.stdout.splitlines()]
    found = {(r[0], r[1]) for r in rows if r and r[0].endswith(".png")}
    assert {("astronaut.png", "person"), ("chelsea.png", "cat"), ("coffee.png", "cup")} <= found, result.stdout
    written = sorted(p.name for p in tmp_path.glob("*_detections.png"))
    assert "coffee_detections.png" in written and len(written) == len(list(SHARED_IMAGES.glob("*.png")))


def test_vision_demo_says_what_to_pass_when_the_model_cannot_load(tmp_path: Path) -> None:
    needs_ssd()
    result = subprocess.run([sys.executable, "-m", "agents_core.demo", "vision", "--model", str(tmp_path / "no.onnx"),
                             "--images", str(SHARED_IMAGES), "--out", str(tmp_path)], capture_output=True, text=True,
                            timeout=120, check=False)
    assert result.returncode == 2 and "--model PATH" in result.stdout, result.stdout + result.stderr[-2000:]
