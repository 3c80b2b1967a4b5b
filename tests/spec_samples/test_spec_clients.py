"""The spec's code, run as written (custom_client.md, custom_model.md): blocks 11-25.

The custom HTTP client of the guide talks to a real HTTP server started here on 127.0.0.1, with the
endpoints the sample calls (``/health``, ``/v1/models/load``, ``/v1/inference``,
``/v1/models/unload``).
"""

from __future__ import annotations

import json
import threading
from collections.abc import Iterator, MutableMapping
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Any

import pytest

from agents_core import Launcher, Topic
from agents_core.clients import client_from_spec
from agents_core.clients.db_base import DBClient
from agents_core.clients.model_base import ModelClient
from agents_core.components import LLM
from agents_core.errors import ConfigError
from agents_core.models import Model, OllamaModel
from agents_core.vectordbs import ChromaDB

from ..conftest import wait_for
from .spec_blocks import covers, run_block

# -- a real server for the custom HTTP client ----------------------------------------------------


class _Handler(BaseHTTPRequestHandler):
    server: _Server

    def log_message(self, format: str, *args: Any) -> None:
        """Quiet."""

    def _reply(self, status: int, body: Any) -> None:
        data = json.dumps(body).encode()
        self.send_response(status)
        self.send_header("Content-Type", "application/json")
        self.send_header("Content-Length", str(len(data)))
        self.end_headers()
        self.wfile.write(data)

    def do_GET(self) -> None:
        self.server.seen.append(("GET", self.path, dict(self.headers), None))
        self._reply(200 if self.path == "/health" else 404, {"ok": True})

    def do_POST(self) -> None:
        length = int(self.headers.get("Content-Length") or 0)
        body = json.loads(self.rfile.read(length) or b"null") if length else None
        self.server.seen.append(("POST", self.path, dict(self.headers), body))
        if self.path == "/v1/inference":
            query = body["query"] if isinstance(body, dict) else None
            text = query[-1]["content"] if isinstance(query, list) else str(query)
            self._reply(200, {"result": f"custom server heard: {text}"})
        elif self.path in ("/v1/models/load", "/v1/models/unload"):
            self._reply(200, {"ok": True})
        else:
            self._reply(404, {"error": "no such route"})


class _Server(ThreadingHTTPServer):
    seen: list[tuple[str, str, dict[str, str], Any]]


@pytest.fixture
def http_server() -> Iterator[_Server]:
    server = _Server(("127.0.0.1", 0), _Handler)
    server.seen = []
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield server
    finally:
        server.shutdown()
        server.server_close()
        thread.join(5)


class _Hooks(ModelClient):
    """The four hooks, for the fragments that show only a constructor or a property."""

    def _check_connection(self) -> None: ...

    def _initialize(self) -> None: ...

    def _inference(self, inference_input: dict[str, Any]) -> MutableMapping[str, Any] | None:
        return {"output": "ok"}

    def _deinitialize(self) -> None: ...


def _as_methods(number: int, base: type, namespace: dict[str, Any] | None = None) -> type:
    """Run a block of methods as the body of a ``base`` subclass."""
    from .spec_blocks import adapted  # noqa: PLC0415

    body = "\n".join("    " + line for line in adapted(number).splitlines())
    ns: dict[str, Any] = {"Base": base, **(namespace or {})}
    exec(f"class Sample(Base):\n{body}\n", ns)
    sample: type = ns["Sample"]
    return sample


# -- custom_client.md ------------------------------------------------------------------------------


@covers((11, "from agents.clients.model_base import ModelClient"))
def test_block_11_the_four_hooks_and_their_order() -> None:
    namespace = run_block(11)
    my_client = namespace["MyClient"]
    client = my_client(OllamaModel(name="m", checkpoint="llama3.2:3b"))  # all four implemented: constructs
    assert client.model_name == "m"
    for hook in ("_check_connection", "_initialize", "_inference", "_deinitialize"):
        lacking = type(f"Lacks{hook}", (ModelClient,), {h: getattr(my_client, h) for h in
                                                         ("_check_connection", "_initialize", "_inference",
                                                          "_deinitialize") if h != hook})
        with pytest.raises(TypeError, match=f"Lacks{hook} must implement {hook}"):
            lacking(OllamaModel(name="m", checkpoint="x"))


@covers((12, 'def __init__(self, model, host="127.0.0.1", port=8080, **kwargs):'))
def test_block_12_constructor_calls_super() -> None:
    sample = _as_methods(12, _Hooks)
    client = sample(OllamaModel(name="m", checkpoint="c"))
    assert (client.host, client.port) == ("127.0.0.1", 8080)
    assert sample(OllamaModel(name="m", checkpoint="c"), inference_timeout=5).inference_timeout == 5


@covers((13, "{"))
def test_block_13_serialize_returns_the_documented_dict() -> None:
    from .spec_blocks import adapted  # noqa: PLC0415

    # The block is a dict with a "..." placeholder among the init params: drop it.
    documented = eval(adapted(13, (', ...}', '}')))
    my_client = type("MyClient", (_Hooks,), {})
    spec = my_client(OllamaModel(name="my_model", checkpoint="llama3.2:3b"), host="127.0.0.1", port=8080).serialize()
    for key, value in documented.items():
        if key == "model":
            assert {k: v for k, v in spec["model"].items() if k != "model_init_params"} == \
                {k: v for k, v in value.items() if k != "model_init_params"}
            assert value["model_init_params"].items() <= spec["model"]["model_init_params"].items()
        elif key == "logging_level":
            assert spec[key].upper() == value  # stored lower-case here (docs/porting.md)
        else:
            assert spec[key] == value, key
    # The keys beyond the spec's example are the ones docs/porting.md names (the `logging_level` row).
    assert set(spec) - set(documented) == {"stream_first_chunk_timeout", "stream_chunk_timeout", "max_reply_bytes"}
    assert client_from_spec(spec) == my_client(OllamaModel(name="my_model", checkpoint="llama3.2:3b"),
                                               host="127.0.0.1", port=8080)


@covers((14, "def __init__(self, model, host=None, port=None, api_key=None, **kwargs):"))
def test_block_14_extra_state_travels_in_serialize() -> None:
    sample = _as_methods(14, _Hooks)
    client = sample(OllamaModel(name="m", checkpoint="c"), api_key="sk-secret")
    spec = client.serialize()
    assert spec["api_key"] == "sk-secret" and spec["client_type"] == "Sample"
    assert client_from_spec(spec).api_key == "sk-secret"
    assert "sk-secret" not in repr(client)


@covers((15, "@property"))
def test_block_15_supports_tool_calls_and_a_client_that_executes_tools_itself() -> None:
    seen: list[dict[str, Any]] = []

    class Executes(_Hooks):
        def _inference(self, inference_input: dict[str, Any]) -> MutableMapping[str, Any] | None:
            seen.append(inference_input)
            # A client that runs the tools itself (the spec's protocol) answers with the final text.
            return {"output": "moved to the kitchen"}

    sample = _as_methods(15, Executes)
    client = sample(OllamaModel(name="m", checkpoint="c"))
    assert client.supports_tool_calls is True and _Hooks(OllamaModel(name="m", checkpoint="c")).supports_tool_calls \
        is False
    q, a = Topic("q", "String"), Topic("a", "String")
    llm = LLM(inputs=[q], outputs=[a], model_client=client, trigger=q)
    def go_to(room: str) -> str:
        return room

    llm.register_tool(go_to, {"name": "go_to", "description": "go to a room", "parameters": {
        "type": "object", "properties": {"room": {"type": "string"}}, "required": ["room"]}})
    launcher = Launcher("memory")
    launcher.add_pkg(components=[llm])
    answers: list[str] = []
    with launcher:
        launcher.transport.create_subscription(a, answers.append)
        launcher.transport.create_publisher(q).publish("go to the kitchen")
        assert wait_for(lambda: bool(answers))
    assert answers == ["moved to the kitchen"]
    assert seen[0]["tools"][0]["function"]["name"] == "go_to", "tool descriptions were in the payload"


@covers((16, "from agents.clients.db_base import DBClient"))
def test_block_16_the_db_client_hooks() -> None:
    namespace = run_block(16)
    my_db = namespace["MyDBClient"]
    client = my_db(db=ChromaDB())  # a DB instance, not a Model
    assert client.db_type == "ChromaDB" and isinstance(client, DBClient)
    hooks = ("_check_connection", "_initialize", "_add", "_conditional_add", "_query", "_metadata_query",
             "_deinitialize")
    for hook in hooks:  # each one the page says a DBClient must implement, refused at construction
        lacking = type(f"Lacks{hook}", (DBClient,), {h: getattr(my_db, h) for h in hooks if h != hook})
        with pytest.raises(TypeError, match=f"Lacks{hook} must implement {hook}"):
            lacking(db=ChromaDB())


@covers((17, "from typing import Any, Dict, Optional, Union, MutableMapping"),
        (18, "from agents.models import GenericLLM"))
def test_blocks_17_18_the_custom_http_client_answers_an_llm(http_server: _Server) -> None:
    namespace = run_block(17)
    port = http_server.server_address[1]
    namespace = run_block(18, namespace, ('host="10.0.0.5", port=5000', f'host="127.0.0.1", port={port}'),
                          ("launcher.bringup()", "pass"))
    launcher, llm = namespace["launcher"], namespace["llm"]
    answers: list[str] = []
    with launcher:
        launcher.transport.create_subscription(namespace["text_out"], answers.append)
        launcher.transport.create_publisher(namespace["text_in"]).publish("hello there")
        assert wait_for(lambda: bool(answers), timeout=15), llm.health_message
    assert answers[0] == "custom server heard: hello there"
    paths = [(method, path) for method, path, _, _ in http_server.seen]
    assert paths[:2] == [("GET", "/health"), ("POST", "/v1/models/load")]
    assert ("POST", "/v1/models/unload") in paths, "the model was unloaded at deactivate"
    loaded = next(body for method, path, _, body in http_server.seen if path == "/v1/models/load")
    assert loaded["checkpoint"] == "my-custom-model"
    auth = next(headers for _, path, headers, _ in http_server.seen if path == "/v1/inference")
    assert auth.get("Authorization") == "Bearer sk-..."
    spec = llm.model_client.serialize()
    assert spec["api_key"] == "sk-..." and client_from_spec(spec).api_key == "sk-..."


# -- custom_model.md -------------------------------------------------------------------------------


@covers((19, "from attrs import define, field"))
def test_block_19_a_model_class_is_kw_only_attrs() -> None:
    namespace = run_block(19, {"Model": Model}, ("    ...\n", "    size: int = field(default=1)\n"))
    my_model = namespace["MyModel"]
    made = my_model(name="m", checkpoint="c", size=2)
    assert (made.name, made.checkpoint, made.size, made.init_timeout) == ("m", "c", 2, None)
    with pytest.raises(TypeError):
        my_model("m", "c")
    from agents_core.ros import BaseAttrs  # noqa: PLC0415

    assert issubclass(Model, BaseAttrs)


@covers((20, "@define(kw_only=True)"))
def test_block_20_the_three_required_fields() -> None:
    from agents_core.ros import BaseAttrs  # noqa: PLC0415

    namespace = run_block(20, {"BaseAttrs": BaseAttrs, "Optional": __import__("typing").Optional,
                               "define": __import__("attrs").define, "field": __import__("attrs").field})
    assert namespace["Model"](name="n", checkpoint="c").init_timeout is None
    made = Model(name="n", checkpoint="c")  # this project's Model has the same three
    assert (made.name, made.checkpoint, made.init_timeout) == ("n", "c", None)
    with pytest.raises((TypeError, ConfigError)):
        Model(checkpoint="c")  # type: ignore[call-arg]


@covers((21, "def _get_init_params(self) -> Dict:"))
def test_block_21_init_params_reach_the_client() -> None:
    import attrs  # noqa: PLC0415

    sample = _as_methods(21, Model, {"Dict": dict})
    with_param = attrs.define(kw_only=True)(type("WithParam", (sample,), {
        "__annotations__": {"my_custom_param": "int"}, "my_custom_param": attrs.field(default=7)}))
    client = _Hooks(with_param(name="n", checkpoint="ckpt"))
    assert client.model_init_params == {"checkpoint": "ckpt", "my_custom_param": 7}
    assert client.serialize()["model"]["model_init_params"] == {"checkpoint": "ckpt", "my_custom_param": 7}


def _turbo() -> dict[str, Any]:
    return run_block(22, {"Model": Model})


@covers((22, "from typing import Optional, Dict, Any"))
def test_block_22_turboserve_model_validates_its_fields() -> None:
    turbo = _turbo()["TurboServeModel"]
    made = turbo(name="t", checkpoint="c")
    assert made._get_init_params() == {"checkpoint": "c", "precision": "fp16", "max_batch_size": 1}
    with pytest.raises((ValueError, ConfigError)):
        turbo(name="t", checkpoint="c", precision="fp8")
    with pytest.raises((ValueError, ConfigError)):
        turbo(name="t", checkpoint="c", max_batch_size=0)


@covers((23, "model = TurboServeModel("))
def test_block_23_the_client_reads_model_init_params() -> None:
    namespace = _turbo()
    namespace["TurboServeClient"] = type("TurboServeClient", (_Hooks,), {})
    namespace = run_block(23, namespace)
    client = namespace["client"]
    assert (client.host, client.port) == ("gpu-server.local", 9000)
    assert client.model_init_params == {"checkpoint": "meta-llama/Llama-3.1-8B", "precision": "fp16",
                                        "max_batch_size": 4}


@covers((24, "@define(kw_only=True)"))
def test_block_24_attrs_post_init_derives_a_field() -> None:
    namespace = run_block(24, {"Model": Model, "Optional": __import__("typing").Optional, "Dict": dict,
                               "define": __import__("attrs").define, "field": __import__("attrs").field})
    made = namespace["TurboServeModel"](name="t", checkpoint="c", precision="fp32")
    assert made._get_init_params()["effective_memory"] == 4
    assert _Hooks(made).model_init_params["effective_memory"] == 4


@covers((25, "@define(kw_only=True)"))
def test_block_25_the_options_dict_is_validated() -> None:
    namespace = run_block(25, {"Model": Model, "Optional": __import__("typing").Optional, "Dict": dict,
                               "Any": Any, "define": __import__("attrs").define, "field": __import__("attrs").field})
    turbo = namespace["TurboServeModel"]
    assert turbo(name="t", checkpoint="c", options={"temperature": 0.2})._get_init_params()["options"] == {
        "temperature": 0.2}
    with pytest.raises(ValueError, match="Invalid option"):
        turbo(name="t", checkpoint="c", options={"beam": 2})
    with pytest.raises(TypeError, match="must be int"):
        turbo(name="t", checkpoint="c", options={"max_tokens": 1.5})
