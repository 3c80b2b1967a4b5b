"""The restricted reader's fast path (the C unpickler under the same rules): it reads what real senders
write exactly as the full reader does, and declines every hostile payload (then the full reader refuses
it), including the ones only a C unpickler would be exposed to."""

from __future__ import annotations

import pickle
import struct
from typing import Any

import numpy as np
import pytest

pytest.importorskip("grpc", reason="the vla extra (grpcio, protobuf) is not installed")

from agents_core.clients.lerobot import fast_pickle as fp
from agents_core.clients.lerobot import protocol as wire
from agents_core.clients.lerobot import restricted_pickle as rp
from agents_core.clients.policy_base import ActionChunkError
from tests.clients import hostile_pickles as hp

LIMITS = rp.PayloadLimits()


def fast(data: bytes) -> Any:
    return fp.fast_loads(data, wire._ALLOWED, max_bytes=1 << 24, what="t", limits=LIMITS)


def full(data: bytes) -> Any:
    """The full (pure-Python) reader alone, as restricted_loads runs it when the fast path declines."""
    reader = rp._Reader(wire._ALLOWED, "t", LIMITS, 1 << 24)
    result = reader.load(data)
    rp._check_result(result, reader)
    return result


def same(a: Any, b: Any) -> bool:
    if type(a) is not type(b):
        return False
    if isinstance(a, np.ndarray):
        return a.dtype == b.dtype and a.shape == b.shape and np.array_equal(a, b) and a.flags.writeable
    if isinstance(a, list | tuple):
        return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(same(a[k], b[k]) for k in a)
    if hasattr(a, "__dict__"):
        return same(vars(a), vars(b))
    return bool(a == b)


def chunk(n: int = 50, width: int = 6) -> bytes:
    rows = np.arange(n * width, dtype=np.float32).reshape(n, width)
    return wire.dumps_payload([wire.TimedAction(0.25 * i, i, rows[i].copy()) for i in range(n)])


def torch_chunk() -> bytes:
    rows = np.arange(8, dtype=np.float32).reshape(4, 2)
    storage = hp.call(hp.glob("torch.storage", "_load_from_bytes"), hp.raw(hp.torch_storage_bytes(rows.tobytes(), 8)))
    memoized = storage + pickle.MEMOIZE
    tensors = [hp.call(hp.glob("torch._utils", "_rebuild_tensor_v2"), memoized if i == 0 else pickle.BINGET + b"\x00",
                       hp.integer(2 * i), hp.tup(hp.integer(2)), hp.tup(hp.integer(1)), pickle.NEWFALSE,
                       hp.call(hp.glob("collections", "OrderedDict"))) for i in range(4)]
    new = hp.glob(hp.HELPERS, "TimedAction") + pickle.EMPTY_TUPLE + pickle.NEWOBJ
    items = b"".join(new + pickle.EMPTY_DICT + pickle.MARK + hp.text("timestamp") + hp.number(0.5)
                     + hp.text("timestep") + hp.integer(i) + hp.text("action") + t + pickle.SETITEMS + pickle.BUILD
                     for i, t in enumerate(tensors))
    return hp.payload(pickle.EMPTY_LIST + pickle.MARK + items + pickle.APPENDS)


@pytest.mark.parametrize("make", [chunk, lambda: chunk(1, 2), torch_chunk, lambda: hp.fuzz_seeds()[0],
                                  lambda: hp.fuzz_seeds()[1], lambda: hp.fuzz_seeds()[2], lambda: hp.fuzz_seeds()[3]],
                         ids=["chunk-50", "chunk-1", "torch-rows", "seed-p4", "seed-p2", "seed-p5", "seed-torch"])
def test_what_senders_write_reads_the_same_on_the_fast_path(make: Any) -> None:
    data = make()
    result = fast(data)
    assert result is not fp.DECLINED
    assert same(result, full(data))
    assert same(rp.restricted_loads(data, wire._ALLOWED, max_bytes=1 << 24), result)


def test_a_chunk_comes_back_as_the_real_payload_class() -> None:
    actions = fast(chunk(3))
    assert [type(a) for a in actions] == [wire.TimedAction] * 3
    assert actions[2].timestep == 2 and actions[2].action.tolist() == [12.0, 13.0, 14.0, 15.0, 16.0, 17.0]


@pytest.mark.parametrize("gadget", sorted(hp.GADGETS))
def test_every_hostile_payload_is_declined_then_refused(gadget: str) -> None:
    data = hp.GADGETS[gadget]()
    assert fast(data) is fp.DECLINED
    with pytest.raises((rp.ProtocolError, ActionChunkError)):  # the full reader's, or the client's shape check
        hp.read_through_the_client(data)


def storage_pid_then(build: bytes) -> bytes:
    """A torch storage whose persistent id's storage type is BUILT with ``build`` (a state) first."""
    good = hp.torch_storage_bytes(b"\0" * 4, 1)
    pid_at = good.index(b"\x80\x02(")  # the fourth small pickle: the persistent id
    head, rest = good[:pid_at], good[pid_at:]
    end = rest.index(pickle.BINPERSID) + 2
    storage_type = hp.glob("torch", "FloatStorage") + build + pickle.BUILD
    pid = (b"\x80\x02" + hp.tup(hp.text("storage"), storage_type, hp.text("0"), hp.text("cpu"), hp.integer(1),
                                pickle.NONE) + pickle.BINPERSID + pickle.STOP)
    storage = hp.call(hp.glob("torch.storage", "_load_from_bytes"), hp.raw(head + pid + rest[end:]))
    return hp.payload(hp.call(hp.glob("torch._utils", "_rebuild_tensor_v2"), storage, hp.integer(0),
                              hp.tup(hp.integer(1)), hp.tup(hp.integer(1)), pickle.NEWFALSE, pickle.NONE))


def test_no_build_can_change_a_shared_allow_listed_object() -> None:
    """The C unpickler sets a BUILD's state on whatever is on the stack: the storage type objects (an
    object dtype code), the payload classes and numpy's marker are never the shared ones."""
    to_object = pickle.EMPTY_DICT + hp.text("code") + hp.text("O") + pickle.SETITEM
    slots = hp.tup(pickle.NONE, to_object)
    for build in (to_object, slots):
        data = storage_pid_then(build)
        assert fast(data) is fp.DECLINED
        with pytest.raises(rp.ProtocolError):
            rp.restricted_loads(data, wire._ALLOWED, max_bytes=1 << 24)
    assert rp._STORAGE_GLOBALS[("torch", "FloatStorage")].code == "f4"
    init = hp.tup(pickle.NONE, pickle.EMPTY_DICT + hp.text("__init__") + pickle.NONE + pickle.SETITEM)
    for target in (hp.glob(hp.HELPERS, "TimedAction"), hp.glob("numpy", "ndarray")):
        data = hp.payload(pickle.EMPTY_LIST + target + init + pickle.BUILD + pickle.APPEND)
        assert fast(data) is fp.DECLINED
    assert wire.TimedAction(1.0, 2, None).timestep == 2 and rp._NDARRAY.name == "numpy.ndarray"
    assert not any("__init__" in vars(c) and vars(c)["__init__"] is None for c in fp._SEALED.values())


@pytest.mark.parametrize("body", [
    pickle.EMPTY_LIST + pickle.PUT + b"67108864\n",  # a text memo index: the C memo table would grow to it
    pickle.EMPTY_LIST + pickle.LONG_BINPUT + struct.pack("<I", 7),  # an index beyond the opcodes seen
    pickle.BYTEARRAY8 + struct.pack("<Q", 1 << 40),  # allocated by the C unpickler before it is read
    pickle.BINBYTES8 + struct.pack("<Q", 1 << 34) + b"abc",
    pickle.BINBYTES + struct.pack("<I", 1 << 31) + b"abc",
    pickle.FRAME + struct.pack("<Q", 1 << 33),
    pickle.EMPTY_TUPLE + pickle.EXT1 + b"\x01",
    hp.glob(hp.HELPERS, "TimedAction") + pickle.EMPTY_TUPLE + pickle.EMPTY_DICT + pickle.NEWOBJ_EX,
    pickle.PERSID + b"0\n",
], ids=["put-text", "long-binput-ahead", "bytearray8", "binbytes8", "binbytes", "frame", "ext1", "newobj-ex", "persid"])
def test_the_scan_declines_what_the_c_unpickler_would_act_on_first(body: bytes) -> None:
    data = hp.payload(body)
    with pytest.raises(fp._Declined):
        fp.scan(data, 0, 200_000)
    assert fast(data) is fp.DECLINED


def test_the_opcode_budget_is_counted_before_the_c_unpickler_runs() -> None:
    data = chunk(50)
    end, bound = fp.scan(data, 0, 200_000)  # fewer bytes than the budget: the bytes read are the bound
    assert end == len(data) and bound == len(data)
    end, ops = fp.scan(data, 0, len(data) - 1)  # otherwise every opcode is counted
    assert end == len(data) and ops == 1851
    with pytest.raises(fp._Declined):
        fp.scan(data, 0, ops - 1)
    tight = rp.PayloadLimits(max_ops=ops - 1)
    assert fp.fast_loads(data, wire._ALLOWED, max_bytes=1 << 24, what="t", limits=tight) is fp.DECLINED
    with pytest.raises(rp.UnsafePayloadError, match="opcodes"):
        rp.restricted_loads(data, wire._ALLOWED, max_bytes=1 << 24, limits=tight)


def test_newobj_with_arguments_and_a_bare_class_are_declined() -> None:
    newobj_args = hp.glob(hp.HELPERS, "TimedAction") + hp.tup(hp.integer(1)) + pickle.NEWOBJ
    assert fast(hp.payload(newobj_args)) is fp.DECLINED
    with pytest.raises(rp.UnsafePayloadError, match="NEWOBJ"):
        rp.restricted_loads(hp.payload(newobj_args), wire._ALLOWED, max_bytes=1 << 24)
    assert fast(hp.payload(hp.glob(hp.HELPERS, "TimedAction"))) is fp.DECLINED


def storage_with_flat(n: int) -> bytes:
    """A torch storage BUILT with ``{"flat": <a (2, n) float32 array>}``, then a tensor of 2n - 1 elements
    from element 1: on a 2-D ``flat`` the storage's bounds check (on ``flat.size``) would pass and the
    view (from row 1) would read n - 1 elements past the array's end."""
    storage = hp.call(hp.glob("torch.storage", "_load_from_bytes"), hp.raw(hp.torch_storage_bytes(b"\0" * 4, 1)))
    rows = hp.call(hp.glob("numpy.core.numeric", "_frombuffer"), hp.raw(np.arange(2 * n, dtype=np.float32).tobytes()),
                   hp.call(hp.glob("numpy", "dtype"), hp.text("f4"), pickle.NEWFALSE, pickle.NEWTRUE),
                   hp.tup(hp.integer(2), hp.integer(n)), hp.text("C"))
    swapped = storage + pickle.EMPTY_DICT + hp.text("flat") + rows + pickle.SETITEM + pickle.BUILD
    return hp.payload(hp.call(hp.glob("torch._utils", "_rebuild_tensor_v2"), swapped, hp.integer(1),
                              hp.tup(hp.integer(2 * n - 1)), hp.tup(hp.integer(1))))


def test_build_on_a_torch_storage_is_declined_then_refused() -> None:
    data = storage_with_flat(4096)
    assert fast(data) is fp.DECLINED
    with pytest.raises(rp.UnsafePayloadError, match="BUILD on a _TorchStorage"):
        rp.restricted_loads(data, wire._ALLOWED, max_bytes=1 << 24)


def test_build_on_an_ordered_dict_is_declined_then_refused() -> None:
    """The C unpickler sets a BUILD's state in an OrderedDict's instance __dict__ (here a bare global,
    which no result check walks into); the full reader refuses BUILD on it."""
    attrs = pickle.EMPTY_DICT + hp.text("keys") + hp.glob("collections", "OrderedDict") + pickle.SETITEM
    data = hp.payload(hp.call(hp.glob("collections", "OrderedDict")) + attrs + pickle.BUILD)
    assert fast(data) is fp.DECLINED
    with pytest.raises(rp.UnsafePayloadError, match="BUILD on a OrderedDict"):
        rp.restricted_loads(data, wire._ALLOWED, max_bytes=1 << 24)
