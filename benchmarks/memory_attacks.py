"""The Memory attacks of issue 36, each in a fresh process, with its peak RSS, wall time and outcome.

``python -m benchmarks.memory_attacks [--src PATH]`` runs every attack against the code at PATH
(default: this checkout's ``src``) and prints a Markdown table; run it once with ``--src`` pointing
at an older checkout for the "before" column. The Memory is the one of
``tests/components/memory_recipe.py`` (hashed-word embeddings, no server), so run it from the
repository root. Not a speed figure: what each attack leaves behind.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import os
import signal
import sqlite3
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]


@contextlib.contextmanager
def _running(m: Any) -> Iterator[Any]:
    from agents_core import Launcher, MemoryTransport  # noqa: PLC0415

    transport = MemoryTransport()
    launcher = Launcher(transport)
    launcher.add_pkg(components=[m])
    try:
        with launcher:
            yield lambda topic, value: transport.create_publisher(topic).publish(value)
    finally:
        transport.close()


def _found(m: Any, n: int, writer: str = "") -> int:
    from tests.components.memory_recipe import WORDS, note  # noqa: PLC0415

    hits = 0
    for i in range(n):
        with contextlib.suppress(Exception):  # an error counts as not found
            hits += note(i, writer) in m.semantic_search(query=f"{writer}note {WORDS[i % len(WORDS)]}", n_results=3)
    return hits


def _notes(m: Any, n: int, writer: str = "") -> int:
    from tests.components.memory_recipe import note  # noqa: PLC0415

    ok = 0
    for i in range(n):
        with contextlib.suppress(Exception):  # an error counts as not stored
            ok += bool(m.store_specific_memory(note(i, writer), x=float(i), y=0.0))
    return ok


def _child(db: Path, *args: str) -> subprocess.Popen[str]:
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    return subprocess.Popen([sys.executable, "-m", "tests.components.memory_recipe", "--transport", "memory",
                             "--db", str(db), *args], cwd=ROOT, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.DEVNULL, text=True, start_new_session=True)


def _ready(proc: subprocess.Popen[str]) -> list[str]:
    lines: list[str] = []
    assert proc.stdout is not None
    for line in proc.stdout:
        lines.append(line.strip())
        if line.strip() == "READY":
            break
    return lines


def attack_nan_z(d: Path) -> str:
    from agents_core.messages import Header, OdometryMsg, PoseMsg  # noqa: PLC0415
    from tests.components.memory_recipe import ODOM, build  # noqa: PLC0415

    m = build(str(d / "m.db"))
    with _running(m) as send:
        send(ODOM, OdometryMsg(pose=PoseMsg(position=[1.0, 1.0, 0.0]), header=Header(frame_id="map")))
        time.sleep(0.3)
        try:
            m.store_specific_memory("poison", z=math.nan)
            first = "accepted"
        except Exception as exc:
            first = f"refused: {str(exc)[:60]}"
        stored = _notes(m, 10)
        found = _found(m, 10)
    return f"z=NaN {first}; then {stored}/10 notes stored, {found}/10 found"


def attack_sigkill(d: Path) -> str:
    from tests.components.memory_recipe import build  # noqa: PLC0415

    proc = _child(d / "m.db", "--notes", "20")
    lines = _ready(proc)
    time.sleep(0.5)
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait(10)
    m = build(str(d / "m.db"))
    with _running(m):
        found = _found(m, 20)
    return f"{lines[0] if lines else 'nothing'}, SIGKILL 0.5 s later; after restart {found}/20 found by meaning"


def attack_two_writers(d: Path) -> str:
    from tests.components.memory_recipe import build  # noqa: PLC0415

    procs = [_child(d / "m.db", "--notes", "20", "--writer", w) for w in ("first", "second")]
    said = [(_ready(p) or ["exited"])[0][:90] for p in procs]
    for p in procs:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(p.pid, signal.SIGINT)
        p.wait(30)
    m = build(str(d / "m.db"))
    with _running(m):
        found = (_found(m, 20, "first"), _found(m, 20, "second"))
    return f"writers said {said}; after restart first {found[0]}/20, second {found[1]}/20 found"


def attack_other_embedder(d: Path) -> str:
    from tests.components.memory_recipe import build  # noqa: PLC0415

    m = build(str(d / "m.db"))
    with _running(m):
        _notes(m, 30)
    out = []
    for dim in (128, 16):
        other = build(str(d / "m.db"), dim=dim)
        with _running(other):
            out.append(f"{dim}-dim: {other.health_status.name}, {_found(other, 30)}/30 right")
    return "; ".join(out)


def attack_damaged_index(d: Path) -> str:
    from tests.components.memory_recipe import build  # noqa: PLC0415

    m = build(str(d / "m.db"))
    with _running(m):
        _notes(m, 20)
    index = d / "m.hnsw.bin"
    index.write_bytes(os.urandom(index.stat().st_size))
    again = build(str(d / "m.db"))
    with _running(again):
        return f"{again.health_status.name}, {_found(again, 20)}/20 found"


def attack_foreign_file(d: Path) -> str:
    from tests.components.memory_recipe import build  # noqa: PLC0415

    db = d / "accounts.db"
    conn = sqlite3.connect(db)
    conn.execute("CREATE TABLE accounts (name TEXT)")
    conn.commit()
    conn.close()
    m = build(str(db))
    with _running(m):
        health = m.health_status.name
    conn = sqlite3.connect(db)
    tables = [r[0] for r in conn.execute("SELECT name FROM sqlite_master WHERE type = 'table'")]
    conn.close()
    return f"{health}; the file now has {len(tables)} table(s); files beside it: {len(list(d.iterdir())) - 1}"


def attack_dev_null(d: Path) -> str:
    from tests.components.memory_recipe import build  # noqa: PLC0415

    existed = os.path.exists("/dev/null-journal")
    m = build("/dev/null")
    with _running(m):
        health = m.health_status.name
    made = os.path.exists("/dev/null-journal") and not existed
    if made:
        os.unlink("/dev/null-journal")
    return f"{health}; /dev/null-journal {'created' if made else 'not created'}"


def attack_hostile_tools(d: Path) -> str:
    from agents_core.errors import ComponentError  # noqa: PLC0415
    from tests.components.memory_recipe import build  # noqa: PLC0415
    from tests.components.test_memory_hardening import HOSTILE  # noqa: PLC0415

    m = build(str(d / "m.db"))
    clear = raw = answered = 0
    with _running(m):
        _notes(m, 5)
        for tool, arguments, _ in HOSTILE:
            try:
                getattr(m, tool)(**arguments)
                answered += 1
            except ComponentError:
                clear += 1
            except Exception:
                raw += 1
    return f"{len(HOSTILE)} calls: {clear} clear errors, {raw} raw library errors, {answered} answered as if valid"


def attack_endless_stream(d: Path) -> str:
    from agents_core import Topic  # noqa: PLC0415
    from agents_core.components import MemLayer, Memory  # noqa: PLC0415
    from agents_core.config import MemoryConfig  # noqa: PLC0415
    from agents_core.messages import Header, OdometryMsg, PoseMsg, StreamingStringMsg  # noqa: PLC0415
    from tests.components.memory_recipe import ODOM, WordEmbedder  # noqa: PLC0415

    said = Topic("said", "StreamingString")
    m = Memory(layers=[MemLayer(subscribes_to=said)], position=ODOM, embedding_client=WordEmbedder(),
               config=MemoryConfig(db_path=str(d / "m.db"), flush_interval=0.0), trigger=20.0)
    with _running(m) as send:
        send(ODOM, OdometryMsg(pose=PoseMsg(position=[1.0, 1.0, 0.0]), header=Header(frame_id="map")))
        time.sleep(0.3)
        chunk = "blah " * 2000  # 10,000 characters
        for _ in range(2000):  # 20 million characters, never done
            send(said, StreamingStringMsg(data=chunk, stream=True, done=False))
        held = sum(len(t) for t in m._partial.values())
    return f"20 M characters streamed, never done: {held:,} characters held"


ATTACKS: dict[str, Callable[[Path], str]] = {
    "1 z=NaN from a peer": attack_nan_z, "1 endless StreamingString": attack_endless_stream,
    "2 SIGKILL after 20 commits": attack_sigkill, "3 two writers, one db": attack_two_writers,
    "4 another embedder (64 -> 128/16)": attack_other_embedder, "11 damaged index file": attack_damaged_index,
    "11 foreign SQLite file": attack_foreign_file, "11 db_path=/dev/null": attack_dev_null,
    "11 hostile tool arguments": attack_hostile_tools,
}


def _measure(name: str, src: str) -> tuple[float, float, str]:
    env = {**os.environ, "PYTHONPATH": f"{src}{os.pathsep}{ROOT}", "AGENTS_QUIET": "1"}
    with tempfile.TemporaryDirectory() as d:
        start = time.monotonic()
        proc = subprocess.Popen([sys.executable, "-m", "benchmarks.memory_attacks", "--one", name, "--dir", d],
                                cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
        timer = threading.Timer(300, proc.kill)  # a hung attack is ended, and says so
        timer.start()
        assert proc.stdout is not None
        out = proc.stdout.read()
        _, status, usage = os.wait4(proc.pid, 0)  # reaped here: its own peak RSS
        timer.cancel()
        elapsed = time.monotonic() - start
    rss = usage.ru_maxrss / 1024
    lines = [line for line in out.splitlines() if line.startswith("{")]
    outcome = json.loads(lines[-1])["outcome"] if lines else f"crashed (exit {os.waitstatus_to_exitcode(status)})"
    return rss, elapsed, outcome


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--src", default=str(ROOT / "src"))
    parser.add_argument("--one", default=None)
    parser.add_argument("--dir", default=None)
    args = parser.parse_args()
    if args.one:
        import logging  # noqa: PLC0415

        logging.disable(logging.CRITICAL)
        print(json.dumps({"outcome": ATTACKS[args.one](Path(args.dir))}), flush=True)
        return
    print("| attack | RSS MB | time s | outcome |\n|---|---|---|---|")
    for name in ATTACKS:
        rss, elapsed, outcome = _measure(name, args.src)
        print(f"| {name} | {rss:.0f} | {elapsed:.1f} | {outcome} |", flush=True)


if __name__ == "__main__":
    main()
