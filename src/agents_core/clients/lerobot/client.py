"""``LeRobotClient``: a policy client for LeRobot's async-inference server (gRPC ``transport.AsyncInference``).

Per inference it streams one observation (``SendObservations``) and asks for the chunk predicted
from it (``GetActions``, repeated while the server answers "none yet", within
``inference_timeout``). At ``initialize`` it says ``Ready`` and sends the policy to load
(``SendPolicyInstructions``: policy type, checkpoint, the observation features, chunk length,
device). See :mod:`agents_core.clients.lerobot.protocol` for the messages.

**Pickles.** LeRobot's payloads are Python pickles, and unpickling runs whatever the bytes name,
so a hostile or impostor server could run code in the robot's process. The client therefore
refuses to start unless built with ``allow_pickle=True``, and even then reads the server's bytes
with a restricted unpickler that admits only the protocol's classes (``TimedAction``, numpy
arrays, and torch tensors through torch's weights-only loader when torch is installed); payloads
are size-bounded. Only point it at a server you run.

Needs the ``vla`` extra (grpcio, protobuf); reading a real LeRobot server's torch tensors also needs
torch.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np

from ...errors import ClientConnectionError, ConfigError, InferenceError, InferenceTimeoutError, ProtocolError
from ...models import LeRobotPolicy, Model
from ...support.install_hint import install_hint
from ..policy_base import ActionChunkError, PolicyClient, action_chunk_array
from .restricted_pickle import PayloadLimits

if TYPE_CHECKING:
    from types import ModuleType

__all__ = ["LeRobotClient"]


def _grpc_and_wire() -> tuple[ModuleType, ModuleType]:
    """grpc and the protocol module, imported when a client first talks (building or rebuilding a client
    from its spec needs neither, so the clients package stays importable without the extra)."""
    try:
        import grpc  # noqa: PLC0415

        from . import protocol as lerobot_protocol  # noqa: PLC0415
    except ImportError as exc:
        raise ConfigError(f"LeRobotClient needs grpcio and protobuf: {install_hint('vla')} ({exc})") from exc
    return grpc, lerobot_protocol

#: Default largest message (either way) and largest actions payload, bytes.
DEFAULT_MAX_MESSAGE_BYTES = 8 * 1024 * 1024
#: Most action values one chunk may hold when the model declares no action names.
DEFAULT_MAX_ACTION_ELEMENTS = 1_000_000


def _same_width(width: int | None, what: str) -> Callable[[tuple[int, ...], np.dtype[Any]], None]:
    """A reader check, run before each array of an actions payload is allocated: every action has the
    first one's size, and that is the declared width (so a wrong chunk costs nothing to refuse)."""
    first: list[int] = []

    def check(shape: tuple[int, ...], dtype: np.dtype[Any]) -> None:
        size = math.prod(shape)
        if not first:
            first.append(size)
            if width is not None and size != width:
                raise ActionChunkError(f"{what}: the policy sent actions of dimension {size}; expected {width}")
        elif size != first[0]:
            raise ProtocolError(f"{what}: the actions of one chunk have different sizes {sorted({first[0], size})}")
    return check


class LeRobotClient(PolicyClient):
    """Client for a LeRobot policy server (``python -m lerobot.async_inference.policy_server``).

    :param model: a :class:`~agents_core.models.LeRobotPolicy` (or its serialized dict).
    :param host: the server's address (default ``"127.0.0.1"``).
    :param port: the server's port (default 8080, LeRobot's).
    :param allow_pickle: must be True: the protocol's payloads are pickles (see the module docs).
    :param rename_map: observation key renames the server applies before the policy (LeRobot's
        ``rename_map``).
    :param max_message_bytes: the largest gRPC message sent or accepted, and the largest actions
        payload read.
    Other parameters as :class:`~agents_core.clients.policy_base.PolicyClient`.
    """

    def __init__(
        self,
        model: LeRobotPolicy | dict[str, Any],
        host: str = "127.0.0.1",
        port: int = 8080,
        allow_pickle: bool = False,
        rename_map: dict[str, str] | None = None,
        max_message_bytes: int = DEFAULT_MAX_MESSAGE_BYTES,
        inference_timeout: int | float = 30,
        init_on_activation: bool = True,
        logging_level: str = "info",
        action_names: list[str] | None = None,
        **kwargs: Any,
    ) -> None:
        if isinstance(model, Model) and not isinstance(model, LeRobotPolicy):
            raise ConfigError(f"LeRobotClient serves LeRobotPolicy models, got a {type(model).__name__}")
        if allow_pickle is not True:
            raise ConfigError("LeRobotClient: LeRobot's async-inference protocol sends Python pickles, which can "
                              "run code from the server; pass allow_pickle=True to accept them (payloads are then "
                              "read with a restricted unpickler that admits only the protocol's classes)")
        if isinstance(max_message_bytes, bool) or not isinstance(max_message_bytes, int) or max_message_bytes < 1024:
            raise ConfigError(f"LeRobotClient: max_message_bytes must be an int >= 1024, got {max_message_bytes!r}")
        if rename_map is not None and not (isinstance(rename_map, dict) and all(
                isinstance(k, str) and isinstance(v, str) for k, v in rename_map.items())):
            raise ConfigError("LeRobotClient: rename_map must map str to str")
        super().__init__(model, host=host, port=port, inference_timeout=inference_timeout,
                         init_on_activation=init_on_activation, logging_level=logging_level,
                         action_names=action_names, **kwargs)
        self.allow_pickle = True
        self.rename_map = dict(rename_map or {})
        self.max_message_bytes = max_message_bytes
        self._channel: Any = None
        self._calls: dict[str, Callable[..., Any]] = {}
        # Set when the server could not be reached: a restarted server has no policy loaded, so the
        # next inference says Ready and sends the policy again first.
        self._needs_setup = False
        #: How many times the policy setup was sent (at initialize, and again when the server lost it).
        self.setups_sent = 0

    # -- connection -------------------------------------------------------------------------------

    def _open(self) -> dict[str, Callable[..., Any]]:
        if self._channel is None:
            grpc, wire = _grpc_and_wire()
            limits = [("grpc.max_receive_message_length", self.max_message_bytes),
                      ("grpc.max_send_message_length", self.max_message_bytes)]
            channel = grpc.insecure_channel(f"{self.host}:{self.port}", options=limits)
            calls: dict[str, Callable[..., Any]] = {}
            for method, (request, response, streaming) in wire.METHODS.items():
                factory = channel.stream_unary if streaming else channel.unary_unary
                calls[method] = factory(f"/{wire.SERVICE}/{method}", request_serializer=request.SerializeToString,
                                        response_deserializer=response.FromString)
            self._channel, self._calls = channel, calls
        return self._calls

    def _close(self) -> None:
        if self._channel is not None:
            self._channel.close()
        self._channel, self._calls = None, {}

    def _rpc(self, method: str, request: Any, timeout: float) -> Any:
        """Call ``method``; gRPC failures become the client's typed errors."""
        grpc, _ = _grpc_and_wire()
        try:
            return self._open()[method](request, timeout=max(timeout, 0.001))
        except grpc.RpcError as exc:
            code = exc.code() if isinstance(exc, grpc.Call) else None
            detail = exc.details() if isinstance(exc, grpc.Call) else str(exc)
            where = f"{self._label()}: {method}"
            if code == grpc.StatusCode.DEADLINE_EXCEEDED:
                raise InferenceTimeoutError(f"{where} timed out after {timeout:.3g} s") from None
            if code == grpc.StatusCode.UNAVAILABLE:
                self._needs_setup = True
                # A fresh channel next time: the old one stays in its reconnect backoff (a second
                # or more) and would fail at once even after the server is back.
                self._close()
                raise ClientConnectionError(f"{where}: cannot reach the server: {detail}") from None
            raise InferenceError(f"{where} failed: {code.name if code else 'error'}: {detail}") from None

    def _check_connection(self) -> None:
        _, wire = _grpc_and_wire()
        self._rpc("Ready", wire.Empty(), float(self.inference_timeout))

    def _initialize(self) -> None:
        self._send_setup(float(self.init_timeout or self.inference_timeout))

    def _send_setup(self, timeout: float) -> None:
        """Say Ready (LeRobot's server resets its queues) and send the policy to load."""
        _, wire = _grpc_and_wire()
        params = self.model_init_params
        features = {name: {**spec, "shape": tuple(spec.get("shape", ()))} if isinstance(spec, dict) else spec
                    for name, spec in (params.get("features") or {}).items()}
        setup = wire.RemotePolicyConfig(policy_type=str(params.get("policy_type")),
                                        pretrained_name_or_path=str(params.get("checkpoint")),
                                        lerobot_features=features,
                                        actions_per_chunk=self._actions_per_chunk(),
                                        device=str(params.get("device", "cpu")), rename_map=dict(self.rename_map))
        deadline = time.monotonic() + timeout
        self._rpc("Ready", wire.Empty(), timeout)
        self._rpc("SendPolicyInstructions", wire.PolicySetup(data=wire.dumps_payload(setup)),
                  deadline - time.monotonic())
        self._needs_setup = False
        self.setups_sent += 1

    def _actions_per_chunk(self) -> int:
        return int(self.model_init_params.get("actions_per_chunk", 50))

    def _deinitialize(self) -> None:
        self._close()

    # -- inference --------------------------------------------------------------------------------

    def _predict(self, observation: dict[str, Any]) -> tuple[int, np.ndarray]:
        _, wire = _grpc_and_wire()
        deadline = time.monotonic() + float(self.inference_timeout)
        if self._needs_setup:
            self._send_setup(deadline - time.monotonic())
        raw: dict[str, Any] = {name: float(value) for name, value in observation["state"].items()}
        for camera, image in observation["images"].items():
            raw[camera] = np.ascontiguousarray(image)
        raw["task"] = observation["task"]
        step = int(observation["timestep"])
        payload = wire.dumps_payload(wire.TimedObservation(timestamp=time.time(), timestep=step, observation=raw,
                                                           must_go=True))
        chunk_size = min(wire.CHUNK_SIZE, self.max_message_bytes - 64)
        self._rpc("SendObservations", wire.chunk_payload(payload, chunk_size), deadline - time.monotonic())
        setup_resent = False
        while True:
            # The server answers no actions when no observation reached its queue in time (it may
            # have dropped ours as a near-duplicate): ask again until the inference deadline.
            left = deadline - time.monotonic()
            if left <= 0:
                raise InferenceTimeoutError(f"{self._label()}: no action chunk within {self.inference_timeout} s")
            answer = self._rpc("GetActions", wire.Empty(), left)
            if answer.data:
                return self._read_actions(answer.data)
            if not setup_resent:
                # Our observation is must_go, so a server that holds a policy answers it. An empty
                # answer is what a server that lost the policy gives (restarted while we were idle:
                # gRPC reconnects silently, and LeRobot logs the missing policy and answers empty).
                # Send the setup and the observation again, once per inference: a healthy server
                # never pays for it, a restarted one costs one extra round trip.
                setup_resent = True
                self.logger.info("%s: no actions for a must_go observation; sending the policy setup again",
                                  self._label())
                self._send_setup(deadline - time.monotonic())
                self._rpc("SendObservations", wire.chunk_payload(payload, chunk_size), deadline - time.monotonic())

    def _read_actions(self, data: bytes) -> tuple[int, np.ndarray]:
        _, wire = _grpc_and_wire()
        what = f"{self._label()}: actions"
        width = len(self.action_names) if self.action_names is not None else None
        rows = max(self._actions_per_chunk(), 1)
        max_elements = rows * width if width is not None else DEFAULT_MAX_ACTION_ELEMENTS
        limits = PayloadLimits(max_elements=max_elements, check_array=_same_width(width, what))
        actions = wire.loads_payload(data, max_bytes=self.max_message_bytes, what=what, limits=limits)
        if not isinstance(actions, list) or not all(isinstance(a, wire.TimedAction) for a in actions):
            raise ProtocolError(f"{what}: expected a list of TimedAction, got {type(actions).__name__}")
        if not actions:
            raise ProtocolError(f"{what}: the server sent an empty chunk")
        steps = [a.timestep for a in actions]
        if any(isinstance(s, bool) or not isinstance(s, int) for s in steps):
            raise ProtocolError(f"{what}: timesteps must be ints")
        if steps != list(range(steps[0], steps[0] + len(steps))):
            raise ProtocolError(f"{what}: the chunk's timesteps are not consecutive: {steps[:5]}...")
        return steps[0], action_chunk_array([a.action for a in actions], what, width=width, max_rows=rows,
                                            max_elements=max_elements)

    def serialize(self) -> dict[str, Any]:
        spec = super().serialize()
        spec.update(allow_pickle=self.allow_pickle, rename_map=dict(self.rename_map),
                    max_message_bytes=self.max_message_bytes)
        return spec
