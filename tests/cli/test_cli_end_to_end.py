"""``agentsctl`` end to end: the recipe in one process, each CLI command in another, on Zenoh and ROS 2.

The recipe (``tests/cli/cli_recipe.py``) is started with ``agentsctl run --transport ...``; every
command runs as ``python -m agents_core.cli`` in its own subprocess and is checked through its
``--json`` output, exit status and one-line errors. Processes are stopped by PID; waits are bounded.
"""

from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from agents_core.testing.helpers import free_tcp_port
from agents_core.testing.pairs import missing_requirement
from tests.cli.helpers import cli, cli_env, cli_json, start, stop, wait_until

pytestmark = pytest.mark.slow

TRANSPORTS = [
    pytest.param("zenoh", marks=[pytest.mark.zenoh, pytest.mark.skipif(
        missing_requirement("zenoh") is not None, reason=str(missing_requirement("zenoh")))]),
    pytest.param("ros2", marks=[pytest.mark.ros2, pytest.mark.skipif(
        missing_requirement("ros2") is not None, reason=str(missing_requirement("ros2")))]),
]


class Running:
    """A recipe started by ``agentsctl run`` and the options every CLI call needs to reach it."""

    def __init__(self, transport: str, options: list[str], process: subprocess.Popen[bytes], log: Path) -> None:
        self.transport = transport
        self.options = options
        self.process = process
        self.log = log

    def json(self, *args: str) -> object:
        return cli_json(*args, *self.options)

    def run(self, *args: str) -> subprocess.CompletedProcess[str]:
        return cli(*args, *self.options)


@pytest.fixture(scope="module", params=TRANSPORTS)
def recipe(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory) -> Iterator[Running]:
    transport = request.param
    log = tmp_path_factory.mktemp(f"cli-{transport}") / "recipe.log"
    env = cli_env()
    options = ["--transport", transport]
    if transport == "zenoh":
        endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
        env = cli_env(AGENTS_ZENOH_LISTEN=endpoint)  # the recipe listens here, the CLI connects as a client
        options += ["--connect", endpoint]
    process = start("run", "tests/cli/cli_recipe.py", "--transport", transport, "all", env=env, log=log)
    running = Running(transport, options, process, log)
    try:
        def both_active() -> bool:
            assert process.poll() is None, log.read_text()
            done = running.run("components", "list", "--json")
            return done.returncode == 0 and sorted((c["name"], c["state"]) for c in json.loads(done.stdout)) == [
                ("listener", "active"), ("talker", "active")]
        assert wait_until(both_active, timeout=90.0), log.read_text()
        yield running
    finally:
        stop(process)


def test_topics_list_shows_types_and_counts(recipe: Running) -> None:
    topics = {t["name"]: t for t in recipe.json("topics", "list")}  # type: ignore[union-attr]
    assert topics["chatter"]["msg_type"] == "String" and topics["chatter"]["publishers"] == 1
    assert topics["camera"]["msg_type"] == "Image" and topics["camera"]["publishers"] == 1
    assert topics["words"]["subscribers"] == 1 and topics["words"]["publishers"] == 0
    assert topics["talker/status"]["msg_type"] == "ComponentStatus"


def test_echo_prints_text_and_summarises_images(recipe: Running) -> None:
    done = recipe.run("topics", "echo", "chatter", "--count", "2", "--json")
    assert done.returncode == 0, done.stderr
    lines = [json.loads(line) for line in done.stdout.splitlines()]
    assert len(lines) == 2 and all(d["msg_type"] == "String" and " " in d["value"] for d in lines)

    done = recipe.run("topics", "echo", "camera", "--count", "1", "--json")
    assert done.returncode == 0, done.stderr
    [image] = [json.loads(line) for line in done.stdout.splitlines()]
    assert image["value"]["data"] == {"shape": [48, 64, 3], "dtype": "uint8"}
    assert image["value"]["header"]["stamp_ns"] > 0
    assert len(done.stdout) < 500  # a summary, never the 9216 pixel bytes

    table = recipe.run("topics", "echo", "camera", "--count", "1")
    assert table.returncode == 0 and "uint8" in table.stdout and "48" in table.stdout


def test_hz_measures_the_talker_rate(recipe: Running) -> None:
    doc = recipe.json("topics", "hz", "chatter", "--window", "2")
    assert isinstance(doc, dict)
    assert doc["messages"] >= 10
    assert 10.0 < doc["rate_hz"] < 30.0  # the talker runs at 20 Hz


def test_pub_reaches_a_component(recipe: Running, tmp_path: Path) -> None:
    echo = subprocess.Popen([sys.executable, "-m", "agents_core.cli", "topics", "echo", "shout", "--count", "1",
                             "--timeout", "60", "--type", "String", "--json", *recipe.options],
                            cwd=Path(__file__).resolve().parents[2], env=cli_env(), stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        # Publish until the echo has its message (each pub waits for a subscriber of "words" first).
        def heard() -> bool:
            done = recipe.run("topics", "pub", "words", "String", "hello cli", "--count", "3")
            assert done.returncode == 0, done.stderr
            return echo.poll() is not None
        assert wait_until(heard, timeout=60.0, interval=0.1)
        out, err = echo.communicate(timeout=10)
        assert echo.returncode == 0, err
        assert json.loads(out.splitlines()[0])["value"] == "HELLO CLI"
    finally:
        if echo.poll() is None:
            echo.kill()
            echo.wait(timeout=10)


def test_components_status_call_and_transition(recipe: Running) -> None:
    status = recipe.json("components", "status", "talker")
    assert isinstance(status, dict)
    assert status["component_type"] == "Talker" and status["run_type"] == "Timed" and status["state"] == "active"
    assert [o["name"] for o in status["outputs"]] == ["chatter", "camera"]
    assert "set_word" in status["actions"]

    called = recipe.json("call", "talker", "set_word", "bonjour")
    assert called == {"component": "talker", "method": "set_word", "result": "now saying bonjour"}
    done = recipe.run("topics", "echo", "chatter", "--count", "1", "--json")
    assert json.loads(done.stdout)["value"].startswith("bonjour ")

    off = recipe.json("components", "transition", "listener", "deactivate")
    assert off == {"component": "listener", "transition": "deactivate", "ok": True, "state": "inactive"}
    on = recipe.json("components", "transition", "listener", "activate")
    assert isinstance(on, dict) and on["ok"] is True and on["state"] == "active"


@pytest.mark.parametrize(("args", "message"), [
    (("topics", "echo", "no_such_topic", "--timeout", "2"), "unknown topic 'no_such_topic'"),
    (("topics", "pub", "words", "Strang", "hi"), "Strang"),
    (("topics", "pub", "numbers", "Float32", "not-a-number"), "does not fit Float32"),
    (("topics", "pub", "bad topic", "String", "x"), "invalid topic name"),
    (("components", "status", "ghost", "--timeout", "2"), "unreachable component 'ghost'"),
    (("call", "ghost", "set_word", "x", "--timeout", "2"), "unreachable component 'ghost'"),
    (("call", "talker", "explode"), "has no action 'explode'"),
    (("call", "talker", "set_word", "--kwargs", "{not json"), "--kwargs is not valid JSON"),
    (("components", "transition", "talker", "fly"), "unknown transition 'fly'"),
])
def test_bad_input_is_one_line_and_non_zero(recipe: Running, args: tuple[str, ...], message: str) -> None:
    done = recipe.run(*args)
    assert done.returncode != 0
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and message in lines[0], done.stderr


def test_ui_attaches_to_the_running_recipe(recipe: Running, tmp_path: Path) -> None:
    """``agentsctl ui`` in its own process serves the recipe's components, found by discovery."""
    pytest.importorskip("starlette", reason="the web UI needs the 'ui' extra")
    import httpx  # noqa: PLC0415 - after the skip check

    port = free_tcp_port()
    log = tmp_path / "ui.log"
    process = start("ui", *recipe.options, "--port", str(port), "--seconds", "120", env=cli_env(), log=log)
    try:
        def described() -> bool:
            assert process.poll() is None, log.read_text()
            try:
                reply = httpx.get(f"http://127.0.0.1:{port}/api/interfaces", timeout=5.0)
            except httpx.HTTPError:
                return False
            return reply.status_code == 200 and {"talker", "listener"} <= {
                c["name"] for c in reply.json()["components"]}
        assert wait_until(described, timeout=60.0), log.read_text()
    finally:
        stop(process)


def test_foxglove_serves_the_running_recipe(recipe: Running, tmp_path: Path) -> None:
    """``agentsctl foxglove`` in its own process: a Foxglove client sees the recipe's image and text."""
    pytest.importorskip("foxglove", reason="needs the 'foxglove' extra")
    pytest.importorskip("google.protobuf", reason="the test client decodes protobuf payloads")
    import asyncio  # noqa: PLC0415

    from tests.foxglove.ws_client import FoxgloveClient  # noqa: PLC0415 - needs websockets + protobuf

    port = free_tcp_port()
    log = tmp_path / "foxglove.log"
    process = start("foxglove", *recipe.options, "--port", str(port), "--seconds", "120", env=cli_env(), log=log)

    async def watch() -> dict[str, object]:
        client = None
        for _ in range(300):  # until the server listens (discovery first): at most ~60 s
            assert process.poll() is None, log.read_text()
            try:
                client = await FoxgloveClient.connect(f"ws://127.0.0.1:{port}")
                break
            except OSError:
                await asyncio.sleep(0.2)
        assert client is not None, log.read_text()
        try:
            await client.wait_for_channels(["/camera", "/chatter"], timeout=30.0)
            for topic in ("/camera", "/chatter"):
                await client.subscribe(topic)
            got: dict[str, object] = {"channels": dict(client.channels)}
            for topic in ("/camera", "/chatter"):
                got[topic] = (await client.next_message(topic, timeout=30.0))[1]
            return got
        finally:
            await client.close()

    try:
        got = asyncio.run(watch())
    finally:
        stop(process)
    channels = got["channels"]
    assert channels["/camera"]["schemaName"] == "foxglove.RawImage"  # type: ignore[index]
    assert channels["/chatter"]["schemaName"] == "foxglove.Log"  # type: ignore[index]
    image = got["/camera"]
    assert (image.width, image.height, image.encoding) == (64, 48, "rgb8")  # type: ignore[attr-defined]
    word, count = got["/chatter"].message.split(" ")  # type: ignore[attr-defined]  # "<word> <n>"
    assert word and int(count) >= 0


def test_ui_refuses_the_memory_transport() -> None:
    done = cli("ui", "--transport", "memory")
    assert done.returncode == 1 and done.stderr.count("\n") == 1 and "zenoh or ros2" in done.stderr
