"""LeRobotClient's wire format against LeRobot's own protocol definitions: the compiled ``services.proto``
of lerobot 0.4.4 (its descriptor, below, is the protocol definition) and its payload dataclasses (their
field names), so a real LeRobot server and our client understand each other without lerobot installed."""

from __future__ import annotations

import base64
import io
import pickle
import pickletools
import subprocess
import sys
import textwrap
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytest.importorskip("grpc", reason="the vla extra (grpcio, protobuf) is not installed")

from google.protobuf import descriptor_pb2, descriptor_pool, message_factory

from agents_core.clients.lerobot import protocol as wire

#: ``lerobot/transport/services.proto`` of lerobot 0.4.4 as compiled into its ``services_pb2.py``
#: (a serialized FileDescriptorProto: services AsyncInference and LearnerService and their messages).
LEROBOT_SERVICES_PROTO = base64.b64decode(
    "CiBsZXJvYm90L3RyYW5zcG9ydC9zZXJ2aWNlcy5wcm90bxIJdHJhbnNwb3J0IkwKClRyYW5zaXRpb24SMAoOdHJhbnNmZXJfc3Rh"
    "dGUYASABKA4yGC50cmFuc3BvcnQuVHJhbnNmZXJTdGF0ZRIMCgRkYXRhGAIgASgMIkwKClBhcmFtZXRlcnMSMAoOdHJhbnNmZXJf"
    "c3RhdGUYASABKA4yGC50cmFuc3BvcnQuVHJhbnNmZXJTdGF0ZRIMCgRkYXRhGAIgASgMIlQKEkludGVyYWN0aW9uTWVzc2FnZRIw"
    "Cg50cmFuc2Zlcl9zdGF0ZRgBIAEoDjIYLnRyYW5zcG9ydC5UcmFuc2ZlclN0YXRlEgwKBGRhdGEYAiABKAwiTQoLT2JzZXJ2YXRp"
    "b24SMAoOdHJhbnNmZXJfc3RhdGUYASABKA4yGC50cmFuc3BvcnQuVHJhbnNmZXJTdGF0ZRIMCgRkYXRhGAIgASgMIhcKB0FjdGlv"
    "bnMSDAoEZGF0YRgBIAEoDCIbCgtQb2xpY3lTZXR1cBIMCgRkYXRhGAEgASgMIgcKBUVtcHR5KmAKDVRyYW5zZmVyU3RhdGUSFAoQ"
    "VFJBTlNGRVJfVU5LTk9XThAAEhIKDlRSQU5TRkVSX0JFR0lOEAESEwoPVFJBTlNGRVJfTUlERExFEAISEAoMVFJBTlNGRVJfRU5E"
    "EAMygQIKDkxlYXJuZXJTZXJ2aWNlEj0KEFN0cmVhbVBhcmFtZXRlcnMSEC50cmFuc3BvcnQuRW1wdHkaFS50cmFuc3BvcnQuUGFy"
    "YW1ldGVyczABEjwKD1NlbmRUcmFuc2l0aW9ucxIVLnRyYW5zcG9ydC5UcmFuc2l0aW9uGhAudHJhbnNwb3J0LkVtcHR5KAESRQoQ"
    "U2VuZEludGVyYWN0aW9ucxIdLnRyYW5zcG9ydC5JbnRlcmFjdGlvbk1lc3NhZ2UaEC50cmFuc3BvcnQuRW1wdHkoARIrCgVSZWFk"
    "eRIQLnRyYW5zcG9ydC5FbXB0eRoQLnRyYW5zcG9ydC5FbXB0eTL1AQoOQXN5bmNJbmZlcmVuY2USPgoQU2VuZE9ic2VydmF0aW9u"
    "cxIWLnRyYW5zcG9ydC5PYnNlcnZhdGlvbhoQLnRyYW5zcG9ydC5FbXB0eSgBEjIKCkdldEFjdGlvbnMSEC50cmFuc3BvcnQuRW1w"
    "dHkaEi50cmFuc3BvcnQuQWN0aW9ucxJCChZTZW5kUG9saWN5SW5zdHJ1Y3Rpb25zEhYudHJhbnNwb3J0LlBvbGljeVNldHVwGhAu"
    "dHJhbnNwb3J0LkVtcHR5EisKBVJlYWR5EhAudHJhbnNwb3J0LkVtcHR5GhAudHJhbnNwb3J0LkVtcHR5YgZwcm90bzM="
)


def lerobot_file() -> descriptor_pb2.FileDescriptorProto:
    return descriptor_pb2.FileDescriptorProto.FromString(LEROBOT_SERVICES_PROTO)


def fields(message: descriptor_pb2.DescriptorProto) -> list[tuple[str, int, int, str]]:
    return [(f.name, f.number, f.type, f.type_name) for f in message.field]


def test_the_messages_have_lerobots_fields_numbers_and_types() -> None:
    theirs = {m.name: m for m in lerobot_file().message_type}
    for name, ours in (("Observation", wire.Observation), ("Actions", wire.Actions),
                       ("PolicySetup", wire.PolicySetup), ("Empty", wire.Empty)):
        mine = descriptor_pb2.DescriptorProto()
        ours.DESCRIPTOR.CopyToProto(mine)
        assert fields(mine) == fields(theirs[name]), name
    enum = next(e for e in lerobot_file().enum_type if e.name == "TransferState")
    assert {v.name: v.number for v in enum.value} == {
        k: getattr(wire.TransferState, k) for k in ("TRANSFER_UNKNOWN", "TRANSFER_BEGIN", "TRANSFER_MIDDLE",
                                                     "TRANSFER_END")}


def test_the_service_methods_match_lerobots_async_inference() -> None:
    proto = lerobot_file()
    service = next(s for s in proto.service if f"{proto.package}.{s.name}" == wire.SERVICE)
    theirs = {m.name: (m.input_type.split(".")[-1], m.output_type.split(".")[-1], m.client_streaming,
                       m.server_streaming) for m in service.method}
    ours = {name: (request.DESCRIPTOR.name, response.DESCRIPTOR.name, streaming, False)
            for name, (request, response, streaming) in wire.METHODS.items()}
    assert ours == theirs


def test_bytes_we_write_are_read_by_lerobots_message_classes() -> None:
    pool = descriptor_pool.DescriptorPool()
    pool.Add(lerobot_file())
    observation = message_factory.GetMessageClass(pool.FindMessageTypeByName("transport.Observation"))
    actions = message_factory.GetMessageClass(pool.FindMessageTypeByName("transport.Actions"))
    theirs = observation.FromString(wire.Observation(transfer_state=2, data=b"abc").SerializeToString())
    assert (theirs.transfer_state, theirs.data) == (2, b"abc")
    assert wire.Actions.FromString(actions(data=b"xyz").SerializeToString()).data == b"xyz"


#: LeRobot's payload dataclasses (lerobot/async_inference/helpers.py): their class paths and field names.
FAKE_LEROBOT = """
from dataclasses import dataclass, field
from typing import Any

@dataclass
class TimedData:
    timestamp: float
    timestep: int

@dataclass
class TimedAction(TimedData):
    action: Any

@dataclass
class TimedObservation(TimedData):
    observation: Any
    must_go: bool = False

@dataclass
class RemotePolicyConfig:
    policy_type: str
    pretrained_name_or_path: str
    lerobot_features: Any
    actions_per_chunk: int
    device: str = "cpu"
    rename_map: dict = field(default_factory=dict)
"""

#: Run where ``lerobot.async_inference.helpers`` is LeRobot's classes (and agents_core is not imported):
#: read our observation with plain pickle as LeRobot's server does, answer actions as it does.
LEROBOT_SIDE = """
import pickle, sys
import numpy as np
from lerobot.async_inference.helpers import TimedAction, TimedObservation
obs = pickle.loads(sys.stdin.buffer.read())
assert type(obs) is TimedObservation, type(obs)
assert obs.timestep == 4 and obs.must_go and obs.observation["task"] == "pick"
assert obs.observation["front"].shape == (4, 4, 3) and obs.observation["elbow"] == 0.5
chunk = [TimedAction(timestamp=obs.timestamp, timestep=obs.timestep + i, action=np.full(2, i, np.float32))
         for i in range(3)]
assert not any(m.startswith("agents_core") for m in sys.modules)
sys.stdout.buffer.write(pickle.dumps(chunk))
"""


def test_payloads_round_trip_with_lerobots_dataclasses(tmp_path: Path) -> None:
    package = tmp_path / "lerobot" / "async_inference"
    package.mkdir(parents=True)
    (tmp_path / "lerobot" / "__init__.py").write_text("")
    (package / "__init__.py").write_text("")
    (package / "helpers.py").write_text(textwrap.dedent(FAKE_LEROBOT))
    ours = wire.TimedObservation(timestamp=1.0, timestep=4, must_go=True,
                                 observation={"elbow": 0.5, "front": np.zeros((4, 4, 3), np.uint8), "task": "pick"})
    done = subprocess.run([sys.executable, "-c", LEROBOT_SIDE], input=wire.dumps_payload(ours), capture_output=True,
                          cwd=tmp_path, env={"PYTHONPATH": str(tmp_path)}, timeout=60, check=False)
    assert done.returncode == 0, done.stderr.decode()[-2000:]
    actions = wire.loads_payload(done.stdout, max_bytes=1 << 20, what="LeRobot actions")
    assert [type(a) for a in actions] == [wire.TimedAction] * 3
    assert [a.timestep for a in actions] == [4, 5, 6]
    assert actions[2].action.tolist() == [2.0, 2.0]


def _pure(obj: Any) -> bytes:
    buffer = io.BytesIO()
    wire._LeRobotPickler(buffer, protocol=4).dump(obj)
    return buffer.getvalue()


class _AsLeRobot(pickle.Unpickler):
    """Plain unpickling with LeRobot's class path resolved to ours (as a process with lerobot has it)."""

    def find_class(self, module: str, name: str) -> Any:
        if module == wire.LEROBOT_HELPERS:
            return getattr(wire, name)
        return super().find_class(module, name)


def test_an_observation_is_pickled_by_the_c_pickler_to_what_the_pure_one_writes() -> None:
    # The fast path (the state by the C pickler, the class around it by name) reads back, with plain
    # pickle and with our reader, as the same object as the pure-Python pickler's bytes.
    image = np.arange(224 * 224 * 3, dtype=np.uint8).reshape(224, 224, 3)
    obs = wire.TimedObservation(timestamp=1.5, timestep=7, must_go=True,
                                observation={"elbow": 0.5, "front": image, "task": "pick", "same": image})
    fast = wire._dumps_fast(obs)
    assert fast is not None and wire.dumps_payload(obs) == fast
    assert fast.startswith(b"\x80\x04\x8c\x1flerobot.async_inference.helpers\x8c\x10TimedObservation\x93)\x81")
    ops = [op.name for op, _arg, _pos in pickletools.genops(fast)]
    assert ops[-2:] == ["BUILD", "STOP"] and ops.count("STOP") == 1
    for data in (fast, _pure(obs)):
        read = _AsLeRobot(io.BytesIO(data)).load()
        assert type(read) is wire.TimedObservation and (read.timestamp, read.timestep, read.must_go) == (1.5, 7, True)
        assert read.observation["task"] == "pick" and read.observation["front"].tobytes() == image.tobytes()
        assert read.observation["same"] is read.observation["front"]  # the memo survives the splice
    mine = wire.loads_payload(fast, max_bytes=1 << 22, what="observation")
    assert type(mine) is wire.TimedObservation and mine.observation["front"].shape == (224, 224, 3)


def test_a_payload_class_inside_a_payload_and_a_list_of_them_take_the_pure_pickler() -> None:
    nested = wire.TimedObservation(timestamp=0.0, timestep=0, observation={"a": wire.TimedAction(0.0, 1, [1.0])})
    assert wire._dumps_fast(nested) is None
    assert wire._dumps_fast([wire.TimedAction(0.0, 1, [1.0])]) is None
    assert wire.dumps_payload(nested) == _pure(nested)
    read = _AsLeRobot(io.BytesIO(wire.dumps_payload(nested))).load()
    assert type(read.observation["a"]) is wire.TimedAction
