"""The policy payload reader under attack: hand-crafted gadgets and Hypothesis-generated pickles, each read
in a subprocess whose exit status is checked (a segfault is exit -11), and the payload forms real senders
write (numpy under protocols 2, 4 and 5, torch's legacy tensor storage) read back exactly."""

from __future__ import annotations

import json
import os
import pickle
import struct
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytest.importorskip("grpc", reason="the vla extra (grpcio, protobuf) is not installed")

from agents_core.clients.lerobot import protocol as wire
from agents_core.clients.lerobot.restricted_pickle import (
    NUMPY_GLOBALS,
    PayloadLimits,
    UnsafePayloadError,
    restricted_loads,
)
from agents_core.clients.policy_base import ActionChunkError
from agents_core.errors import AlgorithmFailure, ProtocolError
from tests.clients import hostile_pickles as hp

ROOT = Path(__file__).resolve().parents[2]


def run_module(*args: str, timeout: float = 300) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT / "src"), str(ROOT)])}
    return subprocess.run([sys.executable, "-m", "tests.clients.hostile_pickles", *args], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=timeout, check=False)


@pytest.mark.parametrize("gadget", sorted(hp.GADGETS))
def test_a_hostile_payload_is_refused_without_crash_or_memory(gadget: str) -> None:
    done = run_module(gadget)
    assert done.returncode == 0, f"exit {done.returncode}: {done.stdout[-800:]} {done.stderr[-2000:]}"
    outcome = json.loads(done.stdout.strip().splitlines()[-1])
    assert "Error" in str(outcome["result"]) and "classes" not in outcome
    assert float(outcome["max_rss_mb"]) < 250, outcome  # the process itself takes ~60 MB
    # A hang guard, not a speed target (the refusal takes ~0.3 s; benchmarks measure speed).
    assert float(outcome["seconds"]) < 60, outcome


@pytest.mark.slow
def test_generated_pickles_end_in_protocol_errors_never_a_crash() -> None:
    done = run_module("--fuzz", "400", timeout=600)
    assert done.returncode == 0, f"exit {done.returncode}: {done.stdout[-2000:]} {done.stderr[-4000:]}"
    assert "fuzzed 400" in done.stdout


def test_a_short_fuzz_run_passes() -> None:
    done = run_module("--fuzz", "60")
    assert done.returncode == 0, f"exit {done.returncode}: {done.stdout[-2000:]} {done.stderr[-4000:]}"


# -- what real senders write is read exactly ------------------------------------------------------

def read(data: bytes, **limits: Any) -> Any:
    return wire.loads_payload(data, max_bytes=1 << 24, what="t", limits=PayloadLimits(**limits) if limits else None)


@pytest.mark.parametrize("protocol", [2, 3, 4, 5])
@pytest.mark.parametrize("array", [
    np.arange(6, dtype=np.float32).reshape(2, 3), np.arange(6, dtype=">f8").reshape(3, 2),
    np.asfortranarray(np.arange(6, dtype=np.int16).reshape(2, 3)), np.array([True, False]), np.zeros((0, 4), np.uint8),
], ids=["f4", "big-endian-f8", "fortran-i2", "bool", "empty"])
def test_numpy_arrays_of_every_protocol_read_back_equal(protocol: int, array: np.ndarray) -> None:
    back = read(pickle.dumps({"a": array, "s": np.float32(1.5), "i": np.int64(-3)}, protocol=protocol))
    assert back["a"].dtype == array.dtype.newbyteorder("=") and np.array_equal(back["a"], array)
    assert back["a"].flags.c_contiguous and back["a"].flags.writeable
    assert back["s"] == np.float32(1.5) and back["i"] == -3


def torch_row(chunk: np.ndarray, row: int) -> bytes:
    """Row ``row`` of a float32 (n, d) tensor as torch pickles a view: the whole storage, an offset, a stride."""
    n, d = chunk.shape
    storage = hp.call(hp.glob("torch.storage", "_load_from_bytes"),
                      hp.raw(hp.torch_storage_bytes(chunk.astype("<f4").tobytes(), n * d)))
    return hp.call(hp.glob("torch._utils", "_rebuild_tensor_v2"), storage, hp.integer(row * d), hp.tup(hp.integer(d)),
                   hp.tup(hp.integer(1)), pickle.NEWFALSE, hp.call(hp.glob("collections", "OrderedDict")))


def test_torch_tensor_rows_as_lerobot_sends_them_read_without_torch() -> None:
    chunk = np.arange(8, dtype=np.float32).reshape(4, 2) / 4
    body = pickle.EMPTY_LIST + pickle.MARK + b"".join(
        hp.timed_action(torch_row(chunk, i), step=10 + i) for i in range(4)) + pickle.APPENDS
    actions = read(hp.payload(body))
    assert [a.timestep for a in actions] == [10, 11, 12, 13]
    assert np.array_equal(np.stack([a.action for a in actions]), chunk)
    transposed = hp.call(hp.glob("torch._utils", "_rebuild_tensor_v2"),
                         hp.call(hp.glob("torch.storage", "_load_from_bytes"),
                                 hp.raw(hp.torch_storage_bytes(chunk.tobytes(), 8))),
                         hp.integer(0), hp.tup(hp.integer(2), hp.integer(4)), hp.tup(hp.integer(1), hp.integer(2)),
                         pickle.NEWFALSE, hp.call(hp.glob("collections", "OrderedDict")))
    assert np.array_equal(read(hp.payload(transposed)), chunk.T)


@pytest.mark.parametrize("storage, offset, size, stride, match", [
    (8, 7, (2,), (1,), "reaches element 8"),
    (8, 0, (3, 3), (3, 1), "reaches element 8"),
    (8, 9, (0,), (1,), "reaches element"),
    (8, 0, (2,), (1, 1), "do not agree"),
    (8, 0, (-1,), (1,), "ints >= 0"),
])
def test_a_tensor_view_outside_its_storage_is_refused(storage: int, offset: int, size: tuple[int, ...],
                                                      stride: tuple[int, ...], match: str) -> None:
    tensor = hp.call(hp.glob("torch._utils", "_rebuild_tensor_v2"),
                     hp.call(hp.glob("torch.storage", "_load_from_bytes"),
                             hp.raw(hp.torch_storage_bytes(b"\0" * 4 * storage, storage))),
                     hp.integer(offset), hp.tup(*map(hp.integer, size)), hp.tup(*map(hp.integer, stride)),
                     pickle.NEWFALSE, hp.call(hp.glob("collections", "OrderedDict")))
    with pytest.raises(UnsafePayloadError, match=match):
        read(hp.payload(tensor))


@pytest.mark.parametrize("storage, match", [("BFloat16Storage", "torch.BFloat16Storage"),
                                            ("ComplexFloatStorage", "not on the allow-list")])
def test_torch_storages_of_other_types_are_refused(storage: str, match: str) -> None:
    data = hp.call(hp.glob("torch.storage", "_load_from_bytes"), hp.raw(hp.torch_storage_bytes(b"\0" * 4, 2, storage)))
    with pytest.raises(UnsafePayloadError, match=match):
        read(hp.payload(data))


# -- the reader's rules, one by one ----------------------------------------------------------------

def test_build_sets_only_declared_fields_of_payload_instances() -> None:
    new = hp.glob(hp.HELPERS, "TimedAction") + pickle.EMPTY_TUPLE + pickle.NEWOBJ
    good = new + pickle.EMPTY_DICT + pickle.MARK + hp.text("timestamp") + hp.number(1.0) + hp.text("timestep") \
        + hp.integer(3) + hp.text("action") + pickle.EMPTY_LIST + pickle.SETITEMS + pickle.BUILD
    assert read(hp.payload(good)) == wire.TimedAction(1.0, 3, [])
    extra = new + pickle.EMPTY_DICT + hp.text("__class__") + pickle.NONE + pickle.SETITEM + pickle.BUILD
    with pytest.raises(UnsafePayloadError, match="fields other than"):
        read(hp.payload(extra))
    with pytest.raises(UnsafePayloadError, match="without"):
        read(hp.payload(new))  # created, never filled
    with pytest.raises(UnsafePayloadError, match="NEWOBJ of OrderedDict"):
        read(hp.payload(hp.glob("collections", "OrderedDict") + pickle.EMPTY_TUPLE + pickle.NEWOBJ))


def test_a_dtype_is_plain_numeric_and_built_once() -> None:
    state = hp.plain_dtype_state()
    for code, match in (("O8", "not a plain numeric"), ("V8", "not a plain numeric"), ("c16", "not a plain")):
        with pytest.raises(UnsafePayloadError, match=match):
            read(hp.payload(hp.dtype(code, state)))
    twice = hp.dtype("f8", state) + state + pickle.BUILD
    with pytest.raises(UnsafePayloadError, match="built twice"):
        read(hp.payload(twice))
    with pytest.raises(UnsafePayloadError, match="state"):
        read(hp.payload(hp.dtype("f8", hp.plain_dtype_state(flags=63))))


def test_array_data_must_match_its_shape_and_the_budget() -> None:
    def array(shape: tuple[int, ...], data: bytes) -> bytes:
        return hp.reconstruct((0,)) + hp.tup(hp.integer(1), hp.tup(*map(hp.integer, shape)),
                                             hp.dtype("f8", hp.plain_dtype_state()), pickle.NEWFALSE,
                                             hp.raw(data)) + pickle.BUILD
    assert read(hp.payload(array((2,), b"\0" * 16))).tolist() == [0.0, 0.0]
    with pytest.raises(UnsafePayloadError, match="16 bytes for shape"):
        read(hp.payload(array((1_000_000_000,), b"\0" * 16)), max_elements=10**12)
    with pytest.raises(UnsafePayloadError, match="size budget"):
        read(hp.payload(array((10**400, 0), b"")))
    with pytest.raises(UnsafePayloadError, match="size budget"):
        read(hp.payload(array((4,), b"\0" * 32)), max_elements=3)
    with pytest.raises(UnsafePayloadError, match="bytes left"):
        read(hp.payload(array((4,), b"\0" * 32)), max_array_bytes=16)


def test_depth_ops_memo_and_bytearray_claims_are_bounded() -> None:
    with pytest.raises(UnsafePayloadError, match="deeper than 32"):
        read(hp.payload(pickle.EMPTY_LIST * 40 + pickle.APPEND * 39))
    with pytest.raises(UnsafePayloadError, match="more than 100 pickle opcodes"):
        read(hp.payload(pickle.EMPTY_LIST + pickle.MARK + pickle.NONE * 200 + pickle.APPENDS), max_ops=100)
    assert read(hp.payload(pickle.EMPTY_LIST + pickle.LONG_BINPUT + struct.pack("<I", 2**32 - 1))) == []
    with pytest.raises(UnsafePayloadError, match="bytearray of 1099511627776 bytes"):
        read(hp.payload(pickle.BYTEARRAY8 + struct.pack("<Q", 2**40)))
    for opcode in (pickle.EXT1 + b"\x01", pickle.INST + b"os\nsystem\n", pickle.OBJ):
        with pytest.raises(UnsafePayloadError, match="opcode that is not allowed"):
            read(hp.payload(pickle.MARK + opcode))
    with pytest.raises(UnsafePayloadError, match="persistent ids"):
        read(hp.payload(hp.text("x") + pickle.BINPERSID))


def test_the_class_is_untouched_after_a_build_on_it() -> None:
    with pytest.raises(UnsafePayloadError, match="BUILD on a type"):
        read(hp.build_on_class())
    assert wire.TimedObservation(1.0, 2, {}).timestep == 2


def test_a_wrong_action_width_is_refused_before_allocating_as_an_algorithm_failure() -> None:
    rows = [wire.TimedAction(0.0, i, np.zeros(3, np.float32)) for i in range(4)]
    with pytest.raises(ActionChunkError, match="dimension 3; expected 2") as caught:
        hp.read_through_the_client(wire.dumps_payload(rows))
    assert isinstance(caught.value, ProtocolError) and isinstance(caught.value, AlgorithmFailure)
    too_many = [wire.TimedAction(0.0, i, np.zeros(2, np.float32)) for i in range(5)]  # the model asks for 4
    with pytest.raises(UnsafePayloadError, match="size budget"):
        hp.read_through_the_client(wire.dumps_payload(too_many))
    same = np.zeros(2)
    memo = [wire.TimedAction(0.0, i, same) for i in range(5)]  # one array, five references
    with pytest.raises(ActionChunkError, match="5 actions in one chunk; at most 4"):
        hp.read_through_the_client(wire.dumps_payload(memo))


def test_the_generic_reader_keeps_its_allow_list() -> None:
    with pytest.raises(UnsafePayloadError, match=r"builtins\.eval"):
        restricted_loads(pickle.dumps(eval), NUMPY_GLOBALS, max_bytes=1000)


@pytest.mark.parametrize("claimed", [2**40, 2**64 - 1])
def test_a_frame_that_claims_more_than_the_payload_holds_is_refused(claimed: int) -> None:
    payload = bytearray(pickle.dumps([1, 2, 3], protocol=4))
    assert payload[2] == pickle.FRAME[0]  # PROTO 4, then FRAME and its 8-byte length
    payload[3:11] = struct.pack("<Q", claimed)
    with pytest.raises(ProtocolError, match="past the end"):
        restricted_loads(bytes(payload), {}, max_bytes=1000)
    with pytest.raises(ProtocolError, match="past the end"):  # the length itself cut short
        restricted_loads(bytes(payload[:6]), {}, max_bytes=1000)
