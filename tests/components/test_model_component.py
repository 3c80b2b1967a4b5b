"""ModelComponent end to end: the spec's DepthEstimator and CustomHTTPClient, health, fallbacks.

The clients here are real classes implementing the ModelClient contract: ``DepthClient``
computes in process, and ``CustomHTTPClient`` (the custom_client.md pattern) talks HTTP to a
real server this test starts on 127.0.0.1.
"""

from __future__ import annotations

import json
import logging
import threading
from collections.abc import Iterator, MutableMapping
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Any

import httpx
import numpy as np
import pytest
from attrs import define, field

from agents_core import Launcher, Topic
from agents_core.actions import Action
from agents_core.clients import ModelClient, client_from_spec
from agents_core.components.model_component import ModelComponent
from agents_core.config import ModelComponentConfig
from agents_core.errors import (
    AlgorithmFailure,
    ClientConnectionError,
    ComponentError,
    ConfigError,
    InferenceError,
    WiringError,
)
from agents_core.models import Model
from agents_core.ros import Event, Image, String, SupportedType, base_validators
from agents_core.status import HealthStatus
from tests.conftest import wait_for

# -- the spec's DepthEstimator, written against agents_core ---------------------------------------


@define(kw_only=True)
class DepthEstimatorConfig(ModelComponentConfig):
    """Configuration for the Depth Estimator component."""

    input_height: int = field(default=8, validator=base_validators.gt(0))
    input_width: int = field(default=8, validator=base_validators.gt(0))
    max_depth: float = field(default=20.0, validator=base_validators.gt(0.0))

    def _get_inference_params(self) -> dict[str, Any]:
        return {"input_height": self.input_height, "input_width": self.input_width}


class DepthEstimator(ModelComponent):
    """Estimates a depth map from camera images."""

    def __init__(self, inputs: Any = None, outputs: Any = None, model_client: Any = None,
                 config: DepthEstimatorConfig | None = None, trigger: Any = 1.0,
                 component_name: str = "depth_estimator", **kwargs: Any) -> None:
        self.allowed_inputs = {"Required": [Image]}
        self.handled_outputs: list[type[SupportedType]] = [Image]
        if not config:
            config = DepthEstimatorConfig()
        super().__init__(inputs=inputs, outputs=outputs, model_client=model_client, config=config,
                         trigger=trigger, component_name=component_name, **kwargs)

    def _create_input(self, *args: Any, **kwargs: Any) -> dict[str, Any] | None:
        image = None
        for cb in self.trig_callbacks.values():
            image = cb.get_output()
        if image is None:
            for cb in self.callbacks.values():
                image = cb.get_output()
        if image is None:
            self.get_logger().warning("No image received yet")
            return None
        return {"images": [image], **self.inference_params}

    def _execution_step(self, **kwargs: Any) -> None:
        inference_input = self._create_input()
        if inference_input is None:
            return
        result = self._call_inference(inference_input)
        self._publish(result)

    def _warmup(self, *args: Any, **kwargs: Any) -> None:
        dummy = np.zeros((self.config.input_height, self.config.input_width, 3), dtype=np.uint8)
        self._call_inference({"images": [dummy], **self.inference_params})

    def _handle_websocket_streaming(self) -> Any:
        return None


@define(kw_only=True)
class DepthModel(Model):
    """A toy depth model description."""

    scale: float = field(default=1.0, validator=base_validators.gt(0.0))

    def _get_init_params(self) -> dict[str, Any]:
        return {"checkpoint": self.checkpoint, "scale": self.scale}


class DepthClient(ModelClient):
    """Computes depth as (255 - grey) in process; ``fail`` makes inference raise like a dead server."""

    def __init__(self, model: Any, fail: bool = False, **kwargs: Any) -> None:
        super().__init__(model=model, **kwargs)
        self.fail = fail
        self.calls: list[dict[str, Any]] = []
        self.events: list[str] = []

    def _check_connection(self) -> None:
        self.events.append("check")

    def _initialize(self) -> None:
        self.events.append("init")

    def _inference(self, inference_input: dict[str, Any]) -> MutableMapping[str, Any] | None:
        self.calls.append(inference_input)
        if self.fail:
            raise ConnectionError("connection refused")
        image = inference_input["images"][0]
        grey = image.mean(axis=2).astype(np.uint8)
        return {"output": (255 - grey).astype(np.uint8)}

    def _deinitialize(self) -> None:
        self.events.append("deinit")

    def serialize(self) -> dict[str, Any]:
        spec = super().serialize()
        spec["fail"] = self.fail
        return spec


def _depth_recipe(client: ModelClient, **kwargs: Any) -> tuple[DepthEstimator, Topic, Topic]:
    camera, depth_map = Topic("camera", "Image"), Topic("depth", "Image")
    depth = DepthEstimator(inputs=[camera], outputs=[depth_map], model_client=client, trigger=camera,
                           config=DepthEstimatorConfig(max_depth=10.0, warmup=True), **kwargs)
    return depth, camera, depth_map


def test_depth_estimator_end_to_end() -> None:
    client = DepthClient(DepthModel(name="depth", checkpoint="toy-depth"))
    depth, camera, depth_map = _depth_recipe(client)
    launcher = Launcher("memory")
    launcher.add_pkg(components=[depth])
    with launcher:
        assert client.events == ["check", "init"]
        assert len(client.calls) == 1, "warmup ran one inference"
        got: list[Any] = []
        launcher.transport.create_subscription(depth_map, got.append)
        frame = np.full((8, 8, 3), 55, np.uint8)
        launcher.transport.create_publisher(camera).publish(frame)
        assert wait_for(lambda: bool(got))
        assert got[0].encoding == "mono8"
        assert int(got[0].data[0, 0, 0]) == 200
        assert client.calls[-1]["input_height"] == 8
    assert client.events[-1] == "deinit"


def test_model_component_wiring_errors() -> None:
    camera = Topic("camera", "Image")
    client = DepthClient(DepthModel(name="d", checkpoint="c"))
    with pytest.raises(WiringError, match="cannot produce String for output 'words'"):
        DepthEstimator(inputs=[camera], outputs=[Topic("words", "String")], model_client=client, trigger=camera)
    with pytest.raises(WiringError, match="needs a model_client"):
        DepthEstimator(inputs=[camera], outputs=[], trigger=camera)
    with pytest.raises(WiringError, match="needs an input topic of type Image"):
        DepthEstimator(inputs=[Topic("t", "String")], outputs=[], model_client=client, trigger=1.0)


def test_failed_inference_sets_health_and_fallback_switches_client() -> None:
    broken = DepthClient(DepthModel(name="depth", checkpoint="remote"), fail=True)
    backup = DepthClient(DepthModel(name="depth", checkpoint="backup"))
    depth, camera, depth_map = _depth_recipe(broken, additional_model_clients={"backup": backup})
    depth.config.warmup = False
    # A server unreachable at run time is an algorithm failure, as upstream (issue 37).
    depth.on_algorithm_fail(Action(depth.change_model_client, args=("backup",)), max_retries=1)
    launcher = Launcher("memory")
    launcher.add_pkg(components=[depth])
    with launcher:
        t = launcher.transport
        statuses: list[Any] = []
        t.create_subscription(depth.status_topic, statuses.append)
        got: list[Any] = []
        t.create_subscription(depth_map, got.append)
        pub = t.create_publisher(camera)
        pub.publish(np.zeros((8, 8, 3), np.uint8))
        assert wait_for(lambda: any(s.health == "ALGORITHM_FAILURE" for s in statuses))
        failure = next(s for s in statuses if s.health == "ALGORITHM_FAILURE")
        assert "InferenceConnectionError" in failure.message
        assert wait_for(lambda: depth.model_client is backup)
        assert backup.events == ["check", "init"]
        pub.publish(np.full((8, 8, 3), 5, np.uint8))
        assert wait_for(lambda: bool(got))
        assert int(got[0].data[0, 0, 0]) == 250, "the backup client answered"
        assert wait_for(lambda: depth.health_status is HealthStatus.HEALTHY)
        assert statuses[-1].health == "HEALTHY" or wait_for(lambda: statuses[-1].health == "HEALTHY")


def test_fallback_gives_up_after_retries() -> None:
    broken = DepthClient(DepthModel(name="depth", checkpoint="remote"), fail=True)
    depth, camera, _ = _depth_recipe(broken)
    depth.config.warmup = False
    attempts: list[str] = []
    gave_up: list[str] = []
    depth.on_any_fail(Action(attempts.append, args=("retry",)), max_retries=2)
    depth.on_giveup(Action(gave_up.append, args=("giving up",)))
    launcher = Launcher("memory")
    launcher.add_pkg(components=[depth])
    with launcher:
        pub = launcher.transport.create_publisher(camera)
        for _ in range(5):
            pub.publish(np.zeros((8, 8, 3), np.uint8))
        assert wait_for(lambda: len(broken.calls) == 5)
        assert wait_for(lambda: depth.failed_steps == 5)
    assert attempts == ["retry", "retry"]
    assert gave_up == ["giving up"]


def test_algorithm_failure_maps_to_its_own_status() -> None:
    class Picky(DepthEstimator):
        def _execution_step(self, **kwargs: Any) -> None:
            raise AlgorithmFailure("no depth edges found")

    client = DepthClient(DepthModel(name="d", checkpoint="c"))
    camera = Topic("camera", "Image")
    comp = Picky(inputs=[camera], outputs=[], model_client=client, trigger=camera)
    ran: list[bool] = []
    comp.on_algorithm_fail(Action(lambda: ran.append(True)))
    launcher = Launcher("memory")
    launcher.add_pkg(components=[comp])
    with launcher:
        launcher.transport.create_publisher(camera).publish(np.zeros((2, 2, 3), np.uint8))
        assert wait_for(lambda: comp.health_status is HealthStatus.ALGORITHM_FAILURE)
        assert wait_for(lambda: ran == [True])


def test_inference_returning_none_is_a_typed_error() -> None:
    class Silent(DepthClient):
        def _inference(self, inference_input: dict[str, Any]) -> MutableMapping[str, Any] | None:
            return None

    client = Silent(DepthModel(name="d", checkpoint="c"))
    with pytest.raises(InferenceError, match="returned nothing"):
        client.inference({})
    with pytest.raises(ClientConnectionError, match="connection refused"):
        DepthClient(DepthModel(name="d", checkpoint="c"), fail=True).inference({"images": []})


def test_event_action_can_switch_model_client() -> None:
    primary = DepthClient(DepthModel(name="depth", checkpoint="remote"))
    backup = DepthClient(DepthModel(name="depth", checkpoint="backup"))
    depth, _, _ = _depth_recipe(primary, additional_model_clients={"backup": backup})
    depth.config.warmup = False
    switch = Topic("switch_model", "String")
    event = Event(name="switch", event_condition=switch.msg.data == "backup")
    launcher = Launcher("memory")
    launcher.add_pkg(components=[depth],
                     events_actions={event: Action(depth.change_model_client, args=(switch.msg.data,))})
    with launcher:
        launcher.transport.create_publisher(switch).publish("backup")
        assert wait_for(lambda: depth.model_client is backup)
        assert primary.events[-1] == "deinit"


# -- clients: serialization, secrets ---------------------------------------------------------------


def test_client_round_trips_through_serialize() -> None:
    client = DepthClient(DepthModel(name="depth", checkpoint="toy", scale=2.0), host="127.0.0.1", port=8000,
                         inference_timeout=12, fail=True)
    spec = client.serialize()
    assert spec["model"]["model_init_params"] == {"checkpoint": "toy", "scale": 2.0}
    rebuilt = client_from_spec(json.loads(json.dumps(spec)))
    assert isinstance(rebuilt, DepthClient)
    assert rebuilt == client
    assert rebuilt.fail is True
    with pytest.raises(ConfigError, match="unknown client type"):
        client_from_spec({"client_type": "NoSuchClient"})


def test_client_arguments_are_validated() -> None:
    model = DepthModel(name="d", checkpoint="c")
    with pytest.raises(ConfigError, match="port"):
        DepthClient(model, port=70000)
    with pytest.raises(ConfigError, match="inference_timeout"):
        DepthClient(model, inference_timeout=0)
    with pytest.raises(ConfigError, match="must be a non-empty str"):
        DepthModel(name="", checkpoint="c")
    with pytest.raises(ConfigError, match=r"scale must be > 0\.0"):
        DepthModel(name="d", checkpoint="c", scale=-1.0)


# -- the custom_client.md pattern against a real HTTP server ----------------------------------------


class CustomHTTPClient(ModelClient):
    """Client for a custom HTTP model server (the custom_client.md skeleton)."""

    def __init__(self, model: Any, host: str = "127.0.0.1", port: int = 5000, inference_timeout: int = 30,
                 api_key: str | None = None, logging_level: str = "info", **kwargs: Any) -> None:
        super().__init__(model=model, host=host, port=port, inference_timeout=inference_timeout,
                         logging_level=logging_level, **kwargs)
        self.api_key = api_key
        self.base_url = f"http://{self.host}:{self.port}"
        self._client: httpx.Client | None = None

    def _check_connection(self) -> None:
        httpx.get(f"{self.base_url}/health", timeout=5.0).raise_for_status()

    def _initialize(self) -> None:
        headers = {"Authorization": f"Bearer {self.api_key}"} if self.api_key else {}
        self._client = httpx.Client(base_url=self.base_url, timeout=self.inference_timeout, headers=headers)
        self._client.post("/v1/models/load", json=self.model_init_params).raise_for_status()
        self.logger.info("Model %s initialized on server", self.model_name)

    def _inference(self, inference_input: dict[str, Any]) -> MutableMapping[str, Any] | None:
        assert self._client is not None
        resp = self._client.post("/v1/inference", json=inference_input)
        resp.raise_for_status()
        return {"output": resp.json().get("result", "")}

    def _deinitialize(self) -> None:
        if self._client:
            self._client.post("/v1/models/unload")
            self._client.close()
            self._client = None

    def serialize(self) -> dict[str, Any]:
        base = super().serialize()
        base["api_key"] = self.api_key
        return base


class _ModelServer(BaseHTTPRequestHandler):
    loaded: dict[str, Any] = {}  # noqa: RUF012  # shared with the test on purpose
    auth: list[str | None] = []  # noqa: RUF012

    def log_message(self, format: str, *args: Any) -> None:
        """Keep the test output quiet."""

    def _reply(self, code: int, body: dict[str, Any]) -> None:
        data = json.dumps(body).encode()
        self.send_response(code)
        self.send_header("Content-Type", "application/json")
        self.send_header("Content-Length", str(len(data)))
        self.end_headers()
        self.wfile.write(data)

    def do_GET(self) -> None:
        self._reply(200, {"ok": True} if self.path == "/health" else {"error": "no such path"})

    def do_POST(self) -> None:
        body = json.loads(self.rfile.read(int(self.headers.get("Content-Length", 0))) or b"{}")
        self.auth.append(self.headers.get("Authorization"))
        if self.path == "/v1/models/load":
            self.loaded.update(body)
            self._reply(200, {"loaded": True})
        elif self.path == "/v1/inference":
            if not self.loaded:
                self._reply(409, {"error": "model not loaded"})
            else:
                self._reply(200, {"result": f"{self.loaded['checkpoint']} says: {body['query'][::-1]}"})
        elif self.path == "/v1/models/unload":
            self.loaded.clear()
            self._reply(200, {})
        else:
            self._reply(404, {"error": "no such path"})


@pytest.fixture
def model_server() -> Iterator[int]:
    server = ThreadingHTTPServer(("127.0.0.1", 0), _ModelServer)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    yield server.server_address[1]
    server.shutdown()
    server.server_close()
    thread.join(5.0)


class Echo(ModelComponent):
    """A minimal text ModelComponent for the HTTP client test."""

    def __init__(self, **kwargs: Any) -> None:
        self.allowed_inputs = {"Required": [String]}
        self.handled_outputs: list[type[SupportedType]] = [String]
        super().__init__(**kwargs)

    def _create_input(self, *args: Any, **kwargs: Any) -> dict[str, Any] | None:
        text = next(iter(self.trig_callbacks.values())).get_output()
        return None if text is None else {"query": text}

    def _execution_step(self, **kwargs: Any) -> None:
        inference_input = self._create_input()
        if inference_input is not None:
            self._publish(self._call_inference(inference_input))

    def _warmup(self, *args: Any, **kwargs: Any) -> None:
        self._call_inference({"query": "warm"})


def test_custom_http_client_end_to_end(model_server: int, caplog: pytest.LogCaptureFixture) -> None:
    secret = "sk-test-secret-123"
    model = Model(name="my_model", checkpoint="my-custom-model")
    client = CustomHTTPClient(model, host="127.0.0.1", port=model_server, api_key=secret, logging_level="debug")
    text_in, text_out = Topic("input_text", "String"), Topic("output_text", "String")
    llm = Echo(inputs=[text_in], outputs=[text_out], model_client=client, trigger=text_in, component_name="echo")
    launcher = Launcher("memory")
    launcher.add_pkg(components=[llm])
    with caplog.at_level(logging.DEBUG), launcher:
        got: list[str] = []
        launcher.transport.create_subscription(text_out, got.append)
        launcher.transport.create_publisher(text_in).publish("olleh")
        assert wait_for(lambda: bool(got))
        assert got == ["my-custom-model says: hello"]
        assert _ModelServer.auth[-1] == f"Bearer {secret}"
    assert _ModelServer.loaded == {}, "deinitialize unloaded the model"
    assert secret not in caplog.text
    assert secret not in repr(client)
    rebuilt = client_from_spec(client.serialize())
    assert rebuilt == client and rebuilt.api_key == secret  # type: ignore[attr-defined]


def test_unreachable_server_fails_configure_with_a_typed_error() -> None:
    client = CustomHTTPClient(Model(name="m", checkpoint="c"), host="127.0.0.1", port=1)
    with pytest.raises(ClientConnectionError, match="cannot reach the server"):
        client.check_connection()


class DepthWithLocal(DepthEstimator):
    """A DepthEstimator with a built-in local model (a plain function here; llama.cpp etc. later)."""

    def _deploy_local_model(self) -> None:
        def local_depth(inference_input: dict[str, Any]) -> dict[str, Any]:
            return {"output": np.full(inference_input["images"][0].shape[:2], 7, np.uint8)}

        self.local_model = local_depth


def test_fallback_to_local_answers_after_client_failure() -> None:
    broken = DepthClient(DepthModel(name="depth", checkpoint="remote"), fail=True)
    camera, depth_map = Topic("camera", "Image"), Topic("depth", "Image")
    depth = DepthWithLocal(inputs=[camera], outputs=[depth_map], model_client=broken, trigger=camera)
    depth.on_algorithm_fail(Action(depth.fallback_to_local))
    launcher = Launcher("memory")
    launcher.add_pkg(components=[depth])
    with launcher:
        got: list[Any] = []
        launcher.transport.create_subscription(depth_map, got.append)
        pub = launcher.transport.create_publisher(camera)
        pub.publish(np.zeros((4, 4, 3), np.uint8))
        assert wait_for(lambda: depth.model_client is None and depth.local_model is not None)
        pub.publish(np.zeros((4, 4, 3), np.uint8))
        assert wait_for(lambda: bool(got))
        assert int(got[0].data[0, 0, 0]) == 7


def test_fallback_to_local_without_a_local_model_is_a_clear_error() -> None:
    client = DepthClient(DepthModel(name="d", checkpoint="c"))
    depth, _, _ = _depth_recipe(client)
    with pytest.raises(ComponentError, match="has no built-in local model"):
        depth.fallback_to_local()
