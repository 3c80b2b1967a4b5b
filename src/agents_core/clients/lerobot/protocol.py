"""LeRobot's async-inference wire protocol: the gRPC service, its messages and its pickled payloads.

The service (package ``transport``, as in LeRobot's ``services.proto``)::

    enum TransferState { TRANSFER_UNKNOWN = 0; TRANSFER_BEGIN = 1; TRANSFER_MIDDLE = 2; TRANSFER_END = 3; }
    message Observation { TransferState transfer_state = 1; bytes data = 2; }
    message Actions     { bytes data = 1; }
    message PolicySetup { bytes data = 1; }
    message Empty       {}
    service AsyncInference {
      rpc SendObservations(stream Observation) returns (Empty);
      rpc GetActions(Empty) returns (Actions);
      rpc SendPolicyInstructions(PolicySetup) returns (Empty);
      rpc Ready(Empty) returns (Empty);
    }

The message classes are built here from that declaration at import (no generated code to keep in
step with the protobuf runtime). ``data`` holds pickles: a ``RemotePolicyConfig`` in
``PolicySetup``, a ``TimedObservation`` split into chunks of at most :data:`CHUNK_SIZE` bytes across
the ``Observation`` stream (BEGIN, MIDDLE..., END; a payload of one chunk is sent as END), and a
list of ``TimedAction`` in ``Actions`` (empty ``data``: no actions yet). Those classes live in
LeRobot's ``lerobot.async_inference.helpers``; :class:`TimedObservation`, :class:`TimedAction` and
:class:`RemotePolicyConfig` here have the same fields and pickle under LeRobot's class paths
(:func:`dumps_payload`), so a LeRobot server reads them as its own. Reading a pickle from the
network runs whatever it names; :func:`loads_payload` admits only the classes in an allow-list.

LeRobot's servers send actions as ``torch.Tensor``; the reader rebuilds them from their storage
bytes as numpy arrays (torch's own unpickling is never used, and torch need not be installed).
"""

from __future__ import annotations

import io
import pickle
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass, field
from typing import Any

from google.protobuf import descriptor_pb2, descriptor_pool, message_factory

from ...errors import ProtocolError
from .restricted_pickle import NUMPY_GLOBALS, TORCH_GLOBALS, PayloadLimits, restricted_loads

__all__ = [
    "CHUNK_SIZE",
    "METHODS",
    "SERVICE",
    "Actions",
    "Empty",
    "Observation",
    "PolicySetup",
    "RemotePolicyConfig",
    "TimedAction",
    "TimedObservation",
    "TransferState",
    "chunk_payload",
    "dumps_payload",
    "join_chunks",
    "loads_payload",
]

#: The gRPC service name (``/<SERVICE>/<method>`` are the method paths).
SERVICE = "transport.AsyncInference"
#: Bytes per Observation chunk (LeRobot's sender uses 2 MiB; gRPC's default message limit is 4 MiB).
CHUNK_SIZE = 2 * 1024 * 1024
#: Where LeRobot defines the pickled payload classes.
LEROBOT_HELPERS = "lerobot.async_inference.helpers"


def _build_messages() -> dict[str, Any]:
    proto = descriptor_pb2.FileDescriptorProto(name="agents_core/lerobot_services.proto", package="transport",
                                               syntax="proto3")
    enum = proto.enum_type.add(name="TransferState")
    for number, name in enumerate(("TRANSFER_UNKNOWN", "TRANSFER_BEGIN", "TRANSFER_MIDDLE", "TRANSFER_END")):
        enum.value.add(name=name, number=number)
    fdp = descriptor_pb2.FieldDescriptorProto
    observation = proto.message_type.add(name="Observation")
    observation.field.add(name="transfer_state", number=1, type=fdp.TYPE_ENUM, type_name=".transport.TransferState",
                          label=fdp.LABEL_OPTIONAL)
    observation.field.add(name="data", number=2, type=fdp.TYPE_BYTES, label=fdp.LABEL_OPTIONAL)
    for name in ("Actions", "PolicySetup"):
        proto.message_type.add(name=name).field.add(name="data", number=1, type=fdp.TYPE_BYTES,
                                                     label=fdp.LABEL_OPTIONAL)
    proto.message_type.add(name="Empty")
    # A private pool: the default one may already hold LeRobot's own file with these names.
    pool = descriptor_pool.DescriptorPool()
    file = pool.Add(proto)
    del file
    return {name: message_factory.GetMessageClass(pool.FindMessageTypeByName(f"transport.{name}"))
            for name in ("Observation", "Actions", "PolicySetup", "Empty")}


_MESSAGES = _build_messages()
#: ``Observation{transfer_state, data}``: one chunk of a pickled TimedObservation.
Observation: Any = _MESSAGES["Observation"]
#: ``Actions{data}``: a pickled list of TimedAction (empty data: none yet).
Actions: Any = _MESSAGES["Actions"]
#: ``PolicySetup{data}``: a pickled RemotePolicyConfig.
PolicySetup: Any = _MESSAGES["PolicySetup"]
#: ``Empty{}``.
Empty: Any = _MESSAGES["Empty"]


class TransferState:
    """The values of the ``TransferState`` enum."""

    TRANSFER_UNKNOWN = 0
    TRANSFER_BEGIN = 1
    TRANSFER_MIDDLE = 2
    TRANSFER_END = 3


#: method name -> (request class, response class, client streams requests).
METHODS: dict[str, tuple[Any, Any, bool]] = {
    "SendObservations": (Observation, Empty, True),
    "GetActions": (Empty, Actions, False),
    "SendPolicyInstructions": (PolicySetup, Empty, False),
    "Ready": (Empty, Empty, False),
}


# -- payload classes (same fields as LeRobot's dataclasses) ------------------------------------------

@dataclass
class TimedObservation:
    """A raw robot observation (joint values by name, camera images by name, ``"task"``) at a timestep."""

    timestamp: float
    timestep: int
    observation: dict[str, Any]
    must_go: bool = False


@dataclass
class TimedAction:
    """One action vector of a chunk, for ``timestep``."""

    timestamp: float
    timestep: int
    action: Any


@dataclass
class RemotePolicyConfig:
    """What the server loads: policy type, checkpoint, the observation features, chunk length, device."""

    policy_type: str
    pretrained_name_or_path: str
    lerobot_features: dict[str, Any]
    actions_per_chunk: int
    device: str = "cpu"
    rename_map: dict[str, str] = field(default_factory=dict)


_PAYLOAD_CLASSES: dict[type, str] = {TimedObservation: "TimedObservation", TimedAction: "TimedAction",
                                     RemotePolicyConfig: "RemotePolicyConfig"}


#: The pure-Python pickler (its save_global can be overridden; typeshed does not describe its internals).
_PurePickler: Any = pickle._Pickler


class _LeRobotPickler(_PurePickler):  # type: ignore[misc]  # an untyped base, on purpose
    # The pure-Python pickler, so that the three payload classes can be written under LeRobot's
    # class path (pickle would otherwise insist on importing lerobot to check the path).
    def save_global(self, obj: Any, name: str | None = None) -> None:
        lerobot_name = _PAYLOAD_CLASSES.get(obj) if isinstance(obj, type) else None
        if lerobot_name is None:
            super().save_global(obj, name)
            return
        self.save(LEROBOT_HELPERS)
        self.save(lerobot_name)
        self.write(pickle.STACK_GLOBAL)
        self.memoize(obj)


class _NestedPayload(Exception):
    """A payload class inside the state: the C pickler would write it under this module's path."""


class _StatePickler(pickle.Pickler):
    """The C pickler, refusing payload classes (only :func:`_dumps_fast` uses it, on a payload's state)."""

    def reducer_override(self, obj: Any) -> Any:
        if type(obj) in _PAYLOAD_CLASSES or (isinstance(obj, type) and obj in _PAYLOAD_CLASSES):
            raise _NestedPayload
        return NotImplemented


def _dumps_fast(obj: Any) -> bytes | None:
    """``obj`` as the pure-Python pickler writes it, with the C pickler (~8x faster on an observation).

    The C pickler cannot write a class under LeRobot's path (it imports the module to check it), so it
    pickles only the object's state, and the object around it is written here: the class by name
    (STACK_GLOBAL), ``copyreg.__newobj__``'s NEWOBJ with no arguments, then BUILD of that state, the
    same opcodes a dataclass pickles to, less their two MEMOIZE (the state's own memo indices then
    start at 0, as in its pickle). The state's STOP becomes the BUILD, inside the state's last frame.
    None when this does not apply (a payload class inside the state): the pure-Python pickler then.
    """
    name = _PAYLOAD_CLASSES.get(type(obj))
    if name is None:
        return None
    buffer = io.BytesIO()
    try:
        _StatePickler(buffer, protocol=4).dump(vars(obj))
    except _NestedPayload:
        return None
    state = buffer.getbuffer()
    if bytes(state[:2]) != _PROTO4 or state[-1] != pickle.STOP[0]:
        return None
    return b"".join((_PROTO4, _short_str(LEROBOT_HELPERS), _short_str(name), pickle.STACK_GLOBAL,
                     pickle.EMPTY_TUPLE, pickle.NEWOBJ, state[2:-1], pickle.BUILD, pickle.STOP))


_PROTO4 = pickle.PROTO + bytes([4])


def _short_str(text: str) -> bytes:
    raw = text.encode()
    return pickle.SHORT_BINUNICODE + bytes([len(raw)]) + raw


def dumps_payload(obj: Any) -> bytes:
    """Pickle ``obj`` (protocol 4) with the payload classes under LeRobot's class paths."""
    fast = _dumps_fast(obj)
    if fast is not None:
        return fast
    buffer = io.BytesIO()
    _LeRobotPickler(buffer, protocol=4).dump(obj)
    return buffer.getvalue()


def _allowed_globals() -> dict[tuple[str, str], Any]:
    allowed = {**NUMPY_GLOBALS, **TORCH_GLOBALS}
    for cls, name in _PAYLOAD_CLASSES.items():
        allowed[(LEROBOT_HELPERS, name)] = cls
        allowed[(__name__, cls.__name__)] = cls
    return allowed


_ALLOWED = _allowed_globals()


def loads_payload(data: bytes, *, max_bytes: int, what: str, limits: PayloadLimits | None = None) -> Any:
    """Unpickle a payload admitting only the payload classes, numpy arrays and CPU torch tensors (read as
    numpy arrays, without torch), within ``limits``; see
    :func:`~agents_core.clients.lerobot.restricted_pickle.restricted_loads`."""
    return restricted_loads(data, _ALLOWED, max_bytes=max_bytes, what=what, limits=limits)


def chunk_payload(data: bytes, chunk_size: int = CHUNK_SIZE) -> Iterator[Any]:
    """``data`` as a stream of ``Observation`` chunks (BEGIN, MIDDLE..., END)."""
    total = len(data)
    offset = 0
    while True:
        end = min(offset + chunk_size, total)
        if end >= total:
            state = TransferState.TRANSFER_END
        elif offset == 0:
            state = TransferState.TRANSFER_BEGIN
        else:
            state = TransferState.TRANSFER_MIDDLE
        yield Observation(transfer_state=state, data=data[offset:end])
        offset = end
        if offset >= total:
            return


def join_chunks(chunks: Iterable[Any], *, max_bytes: int) -> bytes:
    """The payload of an ``Observation`` stream, up to its first END; bounded by ``max_bytes``."""
    parts: list[bytes] = []
    size = 0
    for chunk in chunks:
        state = chunk.transfer_state
        if state == TransferState.TRANSFER_BEGIN:
            parts, size = [], 0
        elif state not in (TransferState.TRANSFER_MIDDLE, TransferState.TRANSFER_END):
            raise ProtocolError(f"LeRobot observation stream: unknown transfer state {state}")
        size += len(chunk.data)
        if size > max_bytes:
            raise ProtocolError(f"LeRobot observation stream: more than {max_bytes} bytes")
        parts.append(chunk.data)
        if state == TransferState.TRANSFER_END:
            return b"".join(parts)
    raise ProtocolError("LeRobot observation stream ended without a TRANSFER_END chunk")


def as_mapping(value: Any, what: str) -> Mapping[str, Any]:
    """``value`` if it is a dict with str keys, else a :class:`ProtocolError` naming ``what``."""
    if not isinstance(value, dict) or not all(isinstance(k, str) for k in value):
        raise ProtocolError(f"{what}: expected a dict with str keys, got {type(value).__name__}")
    return value
