"""Hand-assembled actions payloads a hostile LeRobot policy server could send, and a runner that reads one
through ``LeRobotClient``'s action reader in this process and reports the outcome as one JSON line.

Run (from the repository root; PYTHONPATH picks which agents_core reads it)::

    python -m tests.clients.hostile_pickles dtype_object_field

Exit status: 0 the payload was refused with a ProtocolError; 3 it was accepted; 4 it changed a payload
class for the whole process; anything else (-11: a segfault) is the reader crashing.
"""

from __future__ import annotations

import json
import pickle
import resource
import struct
import sys
import time
from collections.abc import Callable

HELPERS = "lerobot.async_inference.helpers"
NUMPY = "numpy._core.multiarray"
TORCH_MAGIC = 0x1950A86A20F9469CFC6C


# -- a tiny pickle assembler (protocol 4 opcodes; both unpicklers read them under any header) ---------

def text(value: str) -> bytes:
    data = value.encode()
    return pickle.BINUNICODE + struct.pack("<I", len(data)) + data


def raw(value: bytes) -> bytes:
    return pickle.BINBYTES + struct.pack("<I", len(value)) + value


def integer(value: int) -> bytes:
    if 0 <= value < 2**31:
        return pickle.BININT + struct.pack("<i", value)
    body = value.to_bytes((value.bit_length() + 8) // 8, "little", signed=True)
    return pickle.LONG1 + bytes([len(body)]) + body


def number(value: float) -> bytes:
    return pickle.BINFLOAT + struct.pack(">d", value)


def glob(module: str, name: str) -> bytes:
    return pickle.GLOBAL + f"{module}\n{name}\n".encode()


def tup(*items: bytes) -> bytes:
    return pickle.MARK + b"".join(items) + pickle.TUPLE


def call(function: bytes, *args: bytes) -> bytes:
    return function + tup(*args) + pickle.REDUCE


def payload(body: bytes) -> bytes:
    return pickle.PROTO + b"\x04" + body + pickle.STOP


def timed_action(action: bytes, step: int = 0) -> bytes:
    return call(glob(HELPERS, "TimedAction"), number(0.0), integer(step), action)


def one_action_list(action: bytes) -> bytes:
    return payload(pickle.EMPTY_LIST + timed_action(action) + pickle.APPEND)


def dtype(code: str, state: bytes) -> bytes:
    return call(glob("numpy", "dtype"), text(code), pickle.NEWFALSE, pickle.NEWTRUE) + state + pickle.BUILD


def plain_dtype_state(order: str = "<", flags: int = 0) -> bytes:
    return tup(integer(3), text(order), pickle.NONE, pickle.NONE, pickle.NONE, integer(-1), integer(-1), integer(flags))


def reconstruct(shape: tuple[int, ...]) -> bytes:
    return call(glob(NUMPY, "_reconstruct"), glob("numpy", "ndarray"), tup(*(integer(d) for d in shape)), raw(b"b"))


# -- the gadgets ------------------------------------------------------------------------------------

def dtype_object_field() -> bytes:
    """A void dtype whose one field claims objects (flags say none), and an array of raw bytes under it:
    converting it to float dereferences 0x4141414141414141."""
    object_dtype = dtype("O8", plain_dtype_state("|", 63))
    fields = pickle.EMPTY_DICT + text("f0") + tup(object_dtype, integer(0)) + pickle.SETITEM
    void_state = tup(integer(3), text("|"), pickle.NONE, tup(text("f0")), fields, integer(8), integer(1),
                     integer(0))
    void = dtype("V8", void_state)
    array = reconstruct((0,)) + tup(integer(1), tup(integer(1)), void, pickle.NEWFALSE, raw(b"A" * 8)) + pickle.BUILD
    return one_action_list(array)


def build_on_class() -> bytes:
    """BUILD on the allow-listed TimedObservation class itself: setattr(cls, "__init__", None)."""
    mutated = glob(HELPERS, "TimedObservation") + tup(pickle.NONE, pickle.EMPTY_DICT + text("__init__") + pickle.NONE
                                                      + pickle.SETITEM) + pickle.BUILD
    return payload(pickle.EMPTY_LIST + mutated + pickle.APPEND)


def claim_134m_floats() -> bytes:
    """132 bytes: an action of shape (1, 134217728) float64 that numpy's _reconstruct allocates."""
    return one_action_list(call(glob(NUMPY, "_reconstruct"), glob("numpy", "ndarray"),
                                tup(integer(1), integer(134_217_728)), raw(b"d")))


def memo_40m_floats() -> bytes:
    """~11 KB: 1000 actions, each a (40000,) float64 array from memoized _reconstruct arguments."""
    head = (glob(NUMPY, "_reconstruct") + pickle.LONG_BINPUT + struct.pack("<I", 1)
            + tup(glob("numpy", "ndarray"), tup(integer(40_000)), raw(b"d")) + pickle.LONG_BINPUT + struct.pack("<I", 2)
            + pickle.POP + pickle.POP + glob(HELPERS, "TimedAction") + pickle.LONG_BINPUT + struct.pack("<I", 3)
            + pickle.POP)
    get = pickle.BINGET
    rows = b"".join(get + b"\x03" + tup(number(0.0), integer(i), get + b"\x01" + get + b"\x02" + pickle.REDUCE)
                    + pickle.REDUCE for i in range(1000))
    return payload(head + pickle.EMPTY_LIST + pickle.MARK + rows + pickle.APPENDS)


def deep_nesting() -> bytes:
    """An action nested 200,000 lists deep (400 KB)."""
    depth = 200_000
    return one_action_list(pickle.EMPTY_LIST * depth + pickle.APPEND * (depth - 1))


def huge_memo_index() -> bytes:
    """A memo index of 2**26: the C unpickler grows its memo table to 2**27 entries (1 GB) to store it."""
    return payload(pickle.EMPTY_LIST + pickle.LONG_BINPUT + struct.pack("<I", 2**26))


def global_os_system() -> bytes:
    """GLOBAL os.system, called with a shell command."""
    return payload(call(glob("os", "system"), text("echo pwned")))


def torch_stride_zero() -> bytes:
    """A torch tensor of one stored float viewed as (1, 134217728) with stride 0 (a 2.1 GB action)."""
    storage = call(glob("torch.storage", "_load_from_bytes"), raw(torch_storage_bytes(b"\0" * 4, 1)))
    tensor = call(glob("torch._utils", "_rebuild_tensor_v2"), storage, integer(0),
                  tup(integer(1), integer(134_217_728)), tup(integer(0), integer(0)), pickle.NEWFALSE,
                  call(glob("collections", "OrderedDict")))
    return one_action_list(tensor)


def torch_storage_claim() -> bytes:
    """A torch storage that claims 2**33 floats and holds 4 bytes."""
    storage = call(glob("torch.storage", "_load_from_bytes"), raw(torch_storage_bytes(b"\0" * 4, 2**33)))
    tensor = call(glob("torch._utils", "_rebuild_tensor_v2"), storage, integer(0), tup(integer(2)), tup(integer(1)),
                  pickle.NEWFALSE, call(glob("collections", "OrderedDict")))
    return one_action_list(tensor)


def self_reference() -> bytes:
    """An action list that contains itself."""
    return one_action_list(pickle.EMPTY_LIST + pickle.MEMOIZE + pickle.BINGET + b"\x00" + pickle.APPEND)


def torch_storage_bytes(data: bytes, numel: int, storage: str = "FloatStorage", offset_key: str = "0") -> bytes:
    """What ``torch.save(storage, f, _use_new_zipfile_serialization=False)`` writes (protocol 2 pickles)."""
    def small(value: object) -> bytes:
        return pickle.dumps(value, protocol=2)
    pid = (b"\x80\x02" + tup(text("storage"), glob("torch", storage), text(offset_key), text("cpu"), integer(numel),
                             pickle.NONE) + pickle.BINPERSID + pickle.STOP)
    info = {"protocol_version": 1001, "little_endian": True, "type_sizes": {"short": 2, "int": 4, "long": 4}}
    return (small(TORCH_MAGIC) + small(1001) + small(info) + pid + small([offset_key]) + struct.pack("<q", numel)
            + data)


GADGETS: dict[str, Callable[[], bytes]] = {f.__name__: f for f in (
    dtype_object_field, build_on_class, claim_134m_floats, memo_40m_floats, deep_nesting, huge_memo_index,
    global_os_system, torch_stride_zero, torch_storage_claim, self_reference)}


def read_through_the_client(data: bytes) -> object:
    """What LeRobotClient does with a GetActions answer (a 2-joint model, chunks of 4)."""
    from agents_core.clients.lerobot import LeRobotClient  # noqa: PLC0415
    from agents_core.models import LeRobotPolicy  # noqa: PLC0415

    joints = ["shoulder", "elbow"]
    model = LeRobotPolicy(name="p", checkpoint="me/p", policy_type="act", actions_per_chunk=4,
                          features={"observation.state": {"dtype": "float32", "shape": [2], "names": joints}},
                          actions={"action": {"dtype": "float32", "shape": [2], "names": joints}})
    client = LeRobotClient(model, allow_pickle=True, max_message_bytes=8 * 1024 * 1024)
    return client._read_actions(data)


def fuzz_seeds() -> list[bytes]:
    """Valid payloads of every form the reader accepts, and the small gadgets: what mutations start from."""
    import numpy as np  # noqa: PLC0415

    from agents_core.clients.lerobot import protocol as wire  # noqa: PLC0415

    rows = [wire.TimedAction(0.5, i, np.array([0.1 * i, -0.2], np.float32)) for i in range(4)]
    chunk = np.arange(8, dtype=np.float32).reshape(4, 2)
    storage = call(glob("torch.storage", "_load_from_bytes"), raw(torch_storage_bytes(chunk.tobytes(), 8)))
    torch_rows = [call(glob("torch._utils", "_rebuild_tensor_v2"), storage, integer(2 * i), tup(integer(2)),
                       tup(integer(1)), pickle.NEWFALSE, call(glob("collections", "OrderedDict"))) for i in range(4)]
    seeds = [wire.dumps_payload(rows), pickle.dumps(rows, protocol=2).replace(b"agents_core.clients.lerobot.protocol",
                                                                              HELPERS.encode()),
             pickle.dumps([np.float64(1.0), np.zeros((2, 2), ">i4")], protocol=5),
             payload(pickle.EMPTY_LIST + pickle.MARK + b"".join(timed_action(t, i) for i, t in enumerate(torch_rows))
                     + pickle.APPENDS)]
    return seeds + [g() for g in GADGETS.values() if len(g()) < 50_000]


def fuzz(examples: int) -> int:
    """Hypothesis-generated payloads (random bytes, mutated valid payloads, opcode soup) through the client's
    reader: each ends in a ProtocolError or a well-formed chunk, and the payload classes stay intact."""
    import numpy as np  # noqa: PLC0415
    from hypothesis import HealthCheck, given, settings  # noqa: PLC0415
    from hypothesis import strategies as st  # noqa: PLC0415

    from agents_core.clients.lerobot import protocol as wire  # noqa: PLC0415
    from agents_core.errors import ProtocolError  # noqa: PLC0415

    seeds = fuzz_seeds()
    edits = st.lists(st.tuples(st.sampled_from(["set", "insert", "delete"]), st.integers(0, 1 << 20),
                               st.integers(0, 255)), min_size=1, max_size=8)

    def mutate(seed_and_edits: tuple[bytes, list[tuple[str, int, int]]]) -> bytes:
        data = bytearray(seed_and_edits[0])
        for kind, where, value in seed_and_edits[1]:
            at = where % (len(data) + 1)
            if kind == "insert":
                data[at:at] = bytes([value])
            elif data and at < len(data):
                if kind == "set":
                    data[at] = value
                else:
                    del data[at]
        return bytes(data)

    fragments = [pickle.MARK, pickle.TUPLE, pickle.REDUCE, pickle.BUILD, pickle.NEWOBJ, pickle.EMPTY_LIST,
                 pickle.EMPTY_DICT, pickle.APPEND, pickle.APPENDS, pickle.SETITEM, pickle.SETITEMS, pickle.MEMOIZE,
                 pickle.BINGET + b"\x00", pickle.BINGET + b"\x01", pickle.POP, pickle.DUP, pickle.NONE,
                 pickle.NEWFALSE, integer(0), integer(1), integer(2**40), integer(-1), number(0.5), raw(b"\0" * 8),
                 raw(b"b"), text("f0"), text("<"), text("|"), glob("numpy", "dtype"), glob("numpy", "ndarray"),
                 glob(NUMPY, "_reconstruct"), glob(NUMPY, "scalar"), glob("numpy._core.numeric", "_frombuffer"),
                 glob(HELPERS, "TimedAction"), glob(HELPERS, "TimedObservation"), glob("collections", "OrderedDict"),
                 glob("torch._utils", "_rebuild_tensor_v2"), glob("torch.storage", "_load_from_bytes"),
                 text("f8"), text("O8"), text("V8"), plain_dtype_state(), tup(integer(1), integer(2))]
    soup = st.lists(st.sampled_from(fragments), max_size=40).map(lambda parts: payload(b"".join(parts)))
    data_strategy = st.one_of(st.binary(max_size=400), st.tuples(st.sampled_from(seeds), edits).map(mutate), soup)

    @settings(max_examples=examples, database=None, deadline=None, suppress_health_check=list(HealthCheck))
    @given(data_strategy)
    def check(data: bytes) -> None:
        try:
            first, chunk = read_through_the_client(data)  # type: ignore[misc]
        except ProtocolError:
            pass
        else:
            assert isinstance(first, int) and chunk.dtype == np.float64 and chunk.ndim == 2, (first, chunk)
            assert chunk.shape[1] == 2 and 1 <= chunk.shape[0] <= 4, chunk.shape
        wire.TimedObservation(1.0, 1, {})  # the classes are untouched
        wire.TimedAction(1.0, 1, [0.0, 0.0])

    check()
    print(f"fuzzed {examples} payloads", flush=True)
    return 0


def peak_rss_mb() -> float:
    """This process's peak resident size since its exec (VmHWM).

    Not ``getrusage().ru_maxrss``: Linux carries that over fork and exec, so a child of a large
    pytest process would report the parent's peak.
    """
    with open("/proc/self/status", encoding="ascii") as status:
        for line in status:
            if line.startswith("VmHWM:"):
                return round(int(line.split()[1]) / 1024, 1)
    return round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1)


def main(name: str) -> int:
    from agents_core.errors import ProtocolError  # noqa: PLC0415

    data = GADGETS[name]()
    started = time.perf_counter()
    outcome: dict[str, object] = {"gadget": name, "bytes": len(data)}
    code = 3
    try:
        read_through_the_client(data)
        outcome["result"] = "accepted"
    except ProtocolError as exc:
        outcome["result"] = f"{type(exc).__name__}: {str(exc)[:160]}"
        code = 0
    except BaseException as exc:  # the outcome is what is measured
        outcome["result"] = f"{type(exc).__name__}: {str(exc)[:160]}"
        code = 5
    outcome["seconds"] = round(time.perf_counter() - started, 3)
    outcome["max_rss_mb"] = peak_rss_mb()
    from agents_core.clients.lerobot import protocol as wire  # noqa: PLC0415
    try:
        wire.TimedObservation(1.0, 1, {})
        wire.TimedAction(1.0, 1, [0.0, 0.0])
    except Exception as exc:
        outcome["classes"] = f"mutated: {type(exc).__name__}: {exc}"
        code = 4
    print(json.dumps(outcome), flush=True)
    return code


if __name__ == "__main__":
    sys.exit(fuzz(int(sys.argv[2])) if sys.argv[1] == "--fuzz" else main(sys.argv[1]))
