"""The README's demo command must keep working: run it and check what it prints."""

from __future__ import annotations

import subprocess
import sys


def test_demo_prints_the_flow_and_stops_cleanly() -> None:
    result = subprocess.run([sys.executable, "-m", "agents_core.demo", "--seconds", "2"],
                            capture_output=True, text=True, timeout=60, check=False)
    out = result.stdout
    assert result.returncode == 0, result.stderr
    assert "Transport: memory; all active: True" in out
    assert "camera/image  96x64 rgb8 frame_id=camera" in out
    assert "description   'I see a square on the left at x=0.'" in out
    assert "[event] square_on_right fired" in out
    assert out.rstrip().endswith("Stopped cleanly.")
