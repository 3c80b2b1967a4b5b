"""``agentsctl run``: the recipe runs as ``__main__`` with the transport and Zenoh endpoints passed through."""

from __future__ import annotations

import json
from pathlib import Path

from tests.cli.helpers import cli

PROBE = '''
import json, os, sys
from agents_core.transport.registry import resolve_transport

if __name__ == "__main__":
    transport = resolve_transport(None)   # what Launcher() does with no transport
    print(json.dumps({"transport": transport.name, "argv": sys.argv[1:],
                      "connect": os.environ.get("AGENTS_ZENOH_CONNECT"),
                      "mode": os.environ.get("AGENTS_ZENOH_MODE")}))
    transport.close()
'''


def _probe(tmp_path: Path) -> Path:
    recipe = tmp_path / "probe_recipe.py"
    recipe.write_text(PROBE)
    return recipe


def test_run_passes_the_transport_and_the_arguments(tmp_path: Path) -> None:
    done = cli("run", str(_probe(tmp_path)), "--transport", "memory", "--", "--speed", "3")
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout) == {"transport": "memory", "argv": ["--speed", "3"], "connect": None,
                                       "mode": None}


def test_run_sets_the_zenoh_endpoints_without_opening_anything_itself(tmp_path: Path) -> None:
    # The probe only reads the environment (opening a client towards a closed port would fail).
    probe = tmp_path / "env_probe.py"
    probe.write_text("import json, os\nprint(json.dumps({k: v for k, v in os.environ.items() "
                     "if k.startswith('AGENTS_')}))\n")
    done = cli("run", str(probe), "--transport", "zenoh", "--connect", "tcp/10.0.0.2:7447",
               "--connect", "tcp/10.0.0.3:7447", "--mode", "client")
    assert done.returncode == 0, done.stderr
    env = json.loads(done.stdout)
    assert env["AGENTS_TRANSPORT"] == "zenoh"
    assert env["AGENTS_ZENOH_CONNECT"] == "tcp/10.0.0.2:7447,tcp/10.0.0.3:7447"
    assert env["AGENTS_ZENOH_MODE"] == "client"


def test_run_refuses_bad_input_in_one_line(tmp_path: Path) -> None:
    for args, message in (
        (("run", str(tmp_path / "missing.py")), "is not a file"),
        (("run", str(_probe(tmp_path)), "--transport", "mqtt"), "unknown transport 'mqtt'"),
        (("run", str(_probe(tmp_path)), "--mode", "boss"), "unknown Zenoh mode 'boss'"),
    ):
        done = cli(*args)
        assert done.returncode == 1, (args, done.stdout, done.stderr)
        lines = done.stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("error: ") and message in lines[0], done.stderr
