"""Unpickling network payloads without running the sender's code or trusting its memory layout.

A pickle is a small program: every class or function it names is imported and called while it is
loaded, so ``pickle.loads`` on bytes from the network lets the sender run anything. Some protocols
(LeRobot's async inference) still send pickles. :func:`restricted_loads` reads them with a reader
of its own (Python's pure-Python unpickler with its opcodes re-checked), so that:

- a payload may name only the globals in ``allowed`` ((module, name) -> the object to use; anything
  else fails with :class:`UnsafePayloadError` before it is imported). The map also lets a payload's
  class path stand for a local class (``lerobot.async_inference.helpers.TimedAction`` -> our own
  dataclass of the same fields), so the sender's package need not be installed;
- BUILD (``__setstate__``) runs only on *instances* of the allow-listed dataclasses, and sets only
  their declared fields: a payload cannot mutate a class for the whole process;
- arrays are built by the reader, never by numpy's or torch's own unpicklers. :data:`NUMPY_GLOBALS`
  and :data:`TORCH_GLOBALS` map the names numpy and torch pickle arrays and tensors under to
  stand-ins that accept only plain numeric dtypes by name (no dtype object state: no fields, no
  object pointers), check every shape against :class:`PayloadLimits` *before* allocating, and copy
  from bytes that are really in the payload (a length that does not match is refused). Torch
  tensors are read from their legacy storage bytes without importing torch and come back as
  numpy arrays;
- the result is no deeper than ``max_depth``, has no cycles, and the reader runs at most
  ``max_ops`` opcodes (so a small payload cannot become millions of objects).

Anything else a hostile payload can provoke (truncation, bad opcodes, wrong argument types) ends
in :class:`~agents_core.errors.ProtocolError`; refusals by the rules above in its subclass
:class:`UnsafePayloadError`.
"""

from __future__ import annotations

import io
import pickle
import struct
from collections import OrderedDict
from collections.abc import Callable, Mapping
from dataclasses import dataclass, fields, is_dataclass
from typing import Any, Literal

import numpy as np

from ...errors import ProtocolError

__all__ = ["NUMPY_GLOBALS", "TORCH_GLOBALS", "PayloadLimits", "UnsafePayloadError", "restricted_loads"]


class UnsafePayloadError(ProtocolError):
    """A pickled payload breaks the reader's rules: a global outside the allow-list, BUILD on something
    not allow-listed, an array that is not plain numeric or over the size budget, or too many bytes."""


@dataclass(frozen=True)
class PayloadLimits:
    """What one payload may cost the reader, checked before anything is allocated.

    :param max_elements: array elements built from one payload, all arrays together (default: the
        payload's length in bytes, which a payload of real array data cannot exceed).
    :param max_array_elements: elements of any one array (default: no limit beyond ``max_elements``).
    :param max_array_bytes: bytes of the arrays built, all together (default: 8 x ``max_elements``).
    :param max_depth: nesting of containers and payload objects in the result.
    :param max_ops: pickle opcodes executed (one object at most per opcode).
    :param check_array: called with each array's (shape, dtype) before it is allocated; raises a
        :class:`~agents_core.errors.ProtocolError` to refuse it (a caller's shape rule, such as the
        action width).
    """

    max_elements: int | None = None
    max_array_elements: int | None = None
    max_array_bytes: int | None = None
    max_depth: int = 32
    max_ops: int = 200_000
    check_array: Callable[[tuple[int, ...], np.dtype[Any]], None] | None = None


#: numpy dtype codes the reader builds arrays of (numpy pickles a dtype by its code: ``dtype('f4', ...)``).
_NUMERIC_CODES = frozenset({"b1", "i1", "i2", "i4", "i8", "u1", "u2", "u4", "u8", "f2", "f4", "f8"})
#: a dtype's byte order as pickled -> as numpy takes it ("|": not applicable, one-byte types).
_WIRE_ORDERS: dict[str, Literal["<", ">", "="]] = {"<": "<", ">": ">", "|": "=", "=": "="}
_BYTE_ORDERS = frozenset(_WIRE_ORDERS)
_MAX_NDIM = 32


# -- the stand-ins for numpy's and torch's pickled names ---------------------------------------------

class _DTypeSpec:
    """A dtype named by a payload: a numeric code and a byte order, nothing else."""

    __slots__ = ("_native", "_wire", "built", "code", "order")

    def __init__(self, code: Any, align: Any = False, copy: Any = True) -> None:
        if not isinstance(code, str) or code not in _NUMERIC_CODES:
            raise UnsafePayloadError(f"dtype {code!r} is not a plain numeric dtype; refused")
        self.code, self.order, self.built = code, "=", False
        # A payload's arrays share one memoized dtype: made once (the wire one again after BUILD).
        self._native: np.dtype[Any] = np.dtype(code)
        self._wire: np.dtype[Any] | None = None

    def build(self, state: Any) -> _DTypeSpec:
        # numpy's state: (version, byteorder, subarray, names, fields, elsize, alignment, flags[, metadata]).
        # Only a byte order is accepted: fields, subarrays and flags are how a dtype claims object pointers.
        if self.built:
            raise UnsafePayloadError("a dtype is built twice")
        if not (isinstance(state, tuple) and len(state) in (8, 9) and state[0] in (3, 4)
                and state[1] in _BYTE_ORDERS and state[2] is None and state[3] is None and state[4] is None
                and state[5] in (-1, self.itemsize) and type(state[6]) is int and state[7] == 0
                and type(state[7]) is int and (len(state) == 8 or state[8] in (None, {}))):
            raise UnsafePayloadError(f"dtype {self.code!r}: state {str(state)[:120]} is not a plain numeric "
                                     "dtype's; refused")
        self.order, self.built, self._wire = state[1], True, None
        return self

    @property
    def itemsize(self) -> int:
        return int(self.code[1:])

    def wire(self) -> np.dtype[Any]:
        """The dtype of the bytes as sent (made here, from the code)."""
        if self._wire is None:
            self._wire = self._native.newbyteorder(_WIRE_ORDERS[self.order])
        return self._wire

    def native(self) -> np.dtype[Any]:
        return self._native


class _ArrayBuilder:
    """What ``multiarray._reconstruct`` stands for: nothing is allocated until BUILD brings the data."""

    __slots__ = ("result",)

    def __init__(self) -> None:
        self.result: np.ndarray | None = None


class _Marker:
    """A name a payload may mention but not call (``numpy.ndarray`` as _reconstruct's argument)."""

    def __init__(self, name: str) -> None:
        self.name = name


_NDARRAY = _Marker("numpy.ndarray")


@dataclass(frozen=True)
class _StorageType:
    """``torch.FloatStorage`` and friends, inside a torch storage's own pickle."""

    code: str


@dataclass(frozen=True)
class _TorchStorage:
    """A torch storage's elements: a read-only view of the payload's bytes (nothing allocated)."""

    flat: np.ndarray


_TORCH_STORAGE_CODES = {"FloatStorage": "f4", "DoubleStorage": "f8", "HalfStorage": "f2", "LongStorage": "i8",
                        "IntStorage": "i4", "ShortStorage": "i2", "CharStorage": "i1", "ByteStorage": "u1",
                        "BoolStorage": "b1"}
#: torch's legacy file header: magic number, format version.
_TORCH_MAGIC, _TORCH_VERSION = 0x1950A86A20F9469CFC6C, 1001


class _ReaderFunction:
    """An allow-listed function that needs the reader (its budget); bound on each load."""

    def __init__(self, function: Callable[..., Any]) -> None:
        self.function = function


def _reconstruct(subtype: Any, shape: Any, typecode: Any) -> _ArrayBuilder:
    # numpy allocates an empty array of ``shape`` here; the reader allocates nothing (the shape
    # BUILD brings is the one that counts, and it is checked against the data's length).
    if subtype is not _NDARRAY:
        raise UnsafePayloadError("_reconstruct of something other than numpy.ndarray; refused")
    return _ArrayBuilder()


def _scalar(reader: _Reader, dtype: Any, data: Any) -> Any:
    spec = reader.built_dtype(dtype)
    if not isinstance(data, bytes) or len(data) != spec.itemsize:
        raise UnsafePayloadError(f"a numpy scalar of {spec.code!r} needs {spec.itemsize} bytes")
    return np.frombuffer(data, dtype=spec.wire(), count=1).astype(spec.native())[0]


def _frombuffer(reader: _Reader, buffer: Any, dtype: Any, shape: Any, order: Any) -> np.ndarray:
    if order not in ("C", "F"):
        raise UnsafePayloadError(f"array order {order!r}; expected 'C' or 'F'")
    return reader.array_from_bytes(buffer, reader.built_dtype(dtype), shape, fortran=order == "F")


def _load_torch_storage(reader: _Reader, data: Any) -> _TorchStorage:
    """A storage pickled by ``torch.save(storage, _use_new_zipfile_serialization=False)``: four small
    pickles (magic, version, system info, the storage's persistent id), the list of storage keys,
    then per storage its element count (int64, little-endian) and its bytes (little-endian)."""
    if not isinstance(data, bytes):
        raise UnsafePayloadError("a torch storage must be bytes")
    stream = io.BytesIO(data)
    if reader.nested(stream) != _TORCH_MAGIC or reader.nested(stream) != _TORCH_VERSION:
        raise UnsafePayloadError("a torch storage without torch's legacy header")
    info = reader.nested(stream)
    if not isinstance(info, dict) or info.get("little_endian") is not True:
        raise UnsafePayloadError("a torch storage that is not little-endian")
    pid = reader.nested(stream, storage_ids=True)
    keys = reader.nested(stream)
    if not (isinstance(pid, tuple) and len(pid) in (5, 6) and pid[0] == "storage"
            and isinstance(pid[1], _StorageType) and isinstance(pid[2], str) and keys == [pid[2]]
            and type(pid[4]) is int and pid[4] >= 0 and (len(pid) == 5 or pid[5] is None)):
        raise UnsafePayloadError("a torch storage other than one plain storage")
    header = stream.read(8)
    if len(header) != 8 or struct.unpack("<q", header)[0] != pid[4]:
        raise UnsafePayloadError("a torch storage whose element count does not match its header")
    dtype = np.dtype(pid[1].code).newbyteorder("<")
    if len(data) - stream.tell() != pid[4] * dtype.itemsize:
        raise UnsafePayloadError(f"a torch storage claims {pid[4]} elements but holds {len(data) - stream.tell()} "
                                 "bytes")
    return _TorchStorage(np.frombuffer(data, dtype=dtype, count=pid[4], offset=stream.tell()))


def _rebuild_tensor(reader: _Reader, storage: Any, offset: Any, size: Any, stride: Any, requires_grad: Any = False,
                    hooks: Any = None, metadata: Any = None) -> np.ndarray:
    """``torch._utils._rebuild_tensor_v2`` as a numpy copy, after checking every index is in the storage."""
    if not isinstance(storage, _TorchStorage):
        raise UnsafePayloadError("a tensor rebuilt from something other than a storage")
    shape, strides = reader.shape(size), reader.shape(stride)
    if len(strides) != len(shape) or type(offset) is not int or offset < 0 or not isinstance(requires_grad, bool):
        raise UnsafePayloadError("a tensor's offset, size and stride do not agree")
    if not (hooks is None or (isinstance(hooks, dict) and not hooks)) or not (metadata is None
                                                                        or isinstance(metadata, dict)):
        raise UnsafePayloadError("a tensor with backward hooks; refused")
    flat = storage.flat
    count = reader.charge(shape, flat.dtype)
    last = offset + sum((d - 1) * s for d, s in zip(shape, strides, strict=True)) if count else offset - 1
    if last >= flat.size or offset > flat.size:
        raise UnsafePayloadError(f"a tensor reaches element {last} of a storage of {flat.size}")
    view = np.lib.stride_tricks.as_strided(flat[offset:], shape=shape,
                                           strides=[s * flat.itemsize for s in strides], writeable=False)
    return view.astype(flat.dtype.newbyteorder("="), order="C")


def _latin1_bytes(value: Any, encoding: Any = "latin1") -> bytes:
    # Pickle protocols 2 and below write bytes as _codecs.encode(str, "latin1"); no other codec.
    if not isinstance(value, str) or encoding != "latin1":
        raise UnsafePayloadError("_codecs.encode is allowed only as pickle writes bytes (a str, 'latin1')")
    return value.encode("latin1")


def _empty_bytes(*args: Any) -> bytes:
    # ... and empty bytes as bytes() (``__builtin__.bytes`` under protocol 2).
    if args:
        raise UnsafePayloadError("bytes(...) is allowed only empty, as pickle writes b''")
    return b""


def _numpy_globals() -> dict[tuple[str, str], Any]:
    # numpy pickles arrays as multiarray._reconstruct(ndarray, shape, typecode) + BUILD, protocol 5 as
    # numeric._frombuffer(buffer, dtype, shape, order), scalars as multiarray.scalar(dtype, bytes);
    # numpy 2 moved the modules to numpy._core, and a sender may run either version.
    allowed: dict[tuple[str, str], Any] = {("numpy", "ndarray"): _NDARRAY, ("numpy", "dtype"): _DTypeSpec,
                                           ("_codecs", "encode"): _latin1_bytes,
                                           ("__builtin__", "bytes"): _empty_bytes, ("builtins", "bytes"): _empty_bytes}
    for package in ("numpy.core", "numpy._core"):
        allowed[(f"{package}.multiarray", "_reconstruct")] = _reconstruct
        allowed[(f"{package}.multiarray", "scalar")] = _ReaderFunction(_scalar)
        allowed[(f"{package}.numeric", "_frombuffer")] = _ReaderFunction(_frombuffer)
    return allowed


#: The globals a pickle of plain numpy arrays (numeric and bool dtypes) and numpy scalars names.
NUMPY_GLOBALS: Mapping[tuple[str, str], Any] = _numpy_globals()
#: The globals a pickle of CPU torch tensors names (read as numpy arrays; torch is not imported).
TORCH_GLOBALS: Mapping[tuple[str, str], Any] = {
    ("torch._utils", "_rebuild_tensor_v2"): _ReaderFunction(_rebuild_tensor),
    ("torch.storage", "_load_from_bytes"): _ReaderFunction(_load_torch_storage),
    ("collections", "OrderedDict"): OrderedDict,
}
_STORAGE_GLOBALS: Mapping[tuple[str, str], Any] = {("torch", name): _StorageType(code)
                                                   for name, code in _TORCH_STORAGE_CODES.items()}


# -- the reader -------------------------------------------------------------------------------------

_Dispatch = dict[int, Callable[[Any], None]]
_PurePython: Any = pickle._Unpickler  # typeshed does not describe the pure-Python unpickler's internals


class _Reader:
    """One payload's reading: the budget its arrays and opcodes draw from, shared by nested pickles."""

    def __init__(self, allowed: Mapping[tuple[str, str], Any], what: str, limits: PayloadLimits,
                 max_bytes: int) -> None:
        self.allowed, self.what, self.limits = allowed, what, limits
        self.elements_left = limits.max_elements if limits.max_elements is not None else max_bytes
        self.bytes_left = limits.max_array_bytes if limits.max_array_bytes is not None else 8 * self.elements_left
        self.ops_left = limits.max_ops
        self.max_bytes = max_bytes
        self.fields: dict[type, frozenset[str]] = {
            value: frozenset(f.name for f in fields(value)) for value in allowed.values()
            if isinstance(value, type) and is_dataclass(value)}

    def refuse(self, message: str) -> UnsafePayloadError:
        return UnsafePayloadError(f"{self.what}: {message}")

    def load(self, data: bytes) -> Any:
        return _Unpickler(io.BytesIO(data), self, self.allowed).load()

    def nested(self, stream: io.BytesIO, *, storage_ids: bool = False) -> Any:
        """The next pickle in ``stream`` (torch's storage format is several in a row)."""
        unpickler = _Unpickler(stream, self, _STORAGE_GLOBALS)
        unpickler.storage_ids = storage_ids
        return unpickler.load()

    def built_dtype(self, dtype: Any) -> _DTypeSpec:
        if not isinstance(dtype, _DTypeSpec):
            raise self.refuse(f"an array's dtype is a {type(dtype).__name__}, not a numpy dtype")
        return dtype

    def shape(self, value: Any) -> tuple[int, ...]:
        if not isinstance(value, tuple | list) or len(value) > _MAX_NDIM:
            raise self.refuse(f"an array shape must be a tuple of at most {_MAX_NDIM} ints")
        if not all(type(d) is int and d >= 0 for d in value):
            raise self.refuse("an array shape must hold ints >= 0")
        return tuple(value)

    def charge(self, shape: tuple[int, ...], dtype: np.dtype[Any]) -> int:
        """The element count of ``shape``, taken from the budget; refused before any allocation."""
        cap = self.limits.max_array_elements
        cap = self.elements_left if cap is None else min(cap, self.elements_left)
        count = 1
        for d in shape:  # one step at a time, so that a claim of 10**400 never becomes a product
            count *= d
            if count > cap:
                raise self.refuse(f"an array of shape {shape[:8]} is over the size budget ({cap} elements left)")
        if count * dtype.itemsize > self.bytes_left:
            raise self.refuse(f"an array of shape {shape} is over the size budget ({self.bytes_left} bytes left)")
        if self.limits.check_array is not None:
            self.limits.check_array(shape, dtype)
        self.elements_left -= count
        self.bytes_left -= count * dtype.itemsize
        return count

    def array_from_bytes(self, raw: Any, spec: _DTypeSpec, shape: Any, *, fortran: bool) -> np.ndarray:
        if not isinstance(raw, bytes | bytearray):
            raise self.refuse("array data must be bytes (object arrays are refused)")
        dims = self.shape(shape)
        count = self.charge(dims, spec.native())
        if len(raw) != count * spec.itemsize:
            raise self.refuse(f"array data of {len(raw)} bytes for shape {dims} of {spec.code!r}")
        flat = np.frombuffer(raw, dtype=spec.wire(), count=count)
        return flat.reshape(dims, order="F" if fortran else "C").astype(spec.native(), order="C")

    def build_array(self, builder: _ArrayBuilder, state: Any) -> np.ndarray:
        # numpy's ndarray state: ([version,] shape, dtype, is_fortran, rawdata)
        if builder.result is not None:
            raise self.refuse("an array is built twice")
        if isinstance(state, tuple) and len(state) == 5 and state[0] == 1:
            state = state[1:]
        if not (isinstance(state, tuple) and len(state) == 4 and isinstance(state[2], bool)):
            raise self.refuse("an ndarray state that numpy does not write")
        shape, dtype, fortran, raw = state[0], state[1], state[2], state[3]
        builder.result = self.array_from_bytes(raw, self.built_dtype(dtype), shape, fortran=fortran)
        return builder.result

    def over_ops(self) -> UnsafePayloadError:
        return self.refuse(f"more than {self.limits.max_ops} pickle opcodes")


class _Unpickler(_PurePython):  # type: ignore[misc]  # an untyped base, on purpose
    """Python's pure-Python unpickler with the opcodes that reach code or memory re-checked."""

    dispatch: _Dispatch

    def __init__(self, stream: io.BytesIO, reader: _Reader, allowed: Mapping[tuple[str, str], Any]) -> None:
        super().__init__(stream)
        self.reader, self.allowed = reader, allowed
        self.storage_ids = False
        self._stream = stream
        with stream.getbuffer() as view:
            self._size = view.nbytes

    def load(self) -> Any:
        """The pure-Python unpickler's loop, reading the in-memory payload directly (frames are only a
        hint for stream readers; their lengths are still checked) and counting each opcode against
        the reader's budget (shared with nested pickles, hence kept on the reader)."""
        stream, reader = self._stream, self.reader
        read = self.read = stream.read
        self.readline, self.readinto = stream.readline, stream.readinto
        stack: list[Any] = []
        metastack: list[list[Any]] = []
        self.metastack, self.stack, self.proto = metastack, stack, 0
        self.append = stack.append
        dispatch = self.dispatch
        try:
            while True:
                key = read(1)
                if not key:
                    raise EOFError
                reader.ops_left -= 1
                if reader.ops_left < 0:
                    raise reader.over_ops()
                dispatch[key[0]](self)
        except pickle._Stop as stop:  # type: ignore[attr-defined]  # how the pure-Python loop ends
            return stop.value

    def find_class(self, module: str, name: str) -> Any:
        try:
            value = self.allowed[(module, name)]
        except (KeyError, TypeError):
            raise self.reader.refuse(f"the payload names {module}.{name}, which is not on the allow-list; "
                                     "refused without importing it") from None
        if isinstance(value, _ReaderFunction):
            reader, function = self.reader, value.function
            return lambda *args: function(reader, *args)
        return value

    def persistent_load(self, pid: Any) -> Any:
        if not self.storage_ids:
            raise self.reader.refuse("the payload uses persistent ids, which are not allowed")
        return pid  # a torch storage's id tuple, checked by _load_torch_storage

    # -- re-checked opcodes ---------------------------------------------------------------------

    def _build(self) -> None:
        state = self.stack.pop()
        target = self.stack[-1]
        if isinstance(target, _DTypeSpec):
            target.build(state)
        elif isinstance(target, _ArrayBuilder):
            self.stack[-1] = self.reader.build_array(target, state)
        else:
            # Only instances of the allow-listed dataclasses (their exact type: never a class, whose
            # attributes are every instance's), and only their declared fields.
            allowed = self.reader.fields.get(type(target))
            if allowed is None:
                raise self.reader.refuse(f"BUILD on a {type(target).__name__}, which may not be built")
            if not isinstance(state, dict) or not all(type(k) is str and k in allowed for k in state):
                raise self.reader.refuse(f"BUILD of a {type(target).__name__} with fields other than "
                                         f"{sorted(allowed)}")
            vars(target).update(state)

    def _newobj(self) -> None:
        args = self.stack.pop()
        cls = self.stack.pop()
        if cls not in self.reader.fields or args != ():
            raise self.reader.refuse(f"NEWOBJ of {getattr(cls, '__name__', type(cls).__name__)}; only the payload "
                                     "classes may be created")
        self.append(cls.__new__(cls))

    def _refused(self) -> None:
        raise self.reader.refuse("the payload uses an opcode that is not allowed (extension registry, INST/OBJ, "
                                 "NEWOBJ_EX)")

    def _frame(self) -> None:
        header = self.read(8)
        if len(header) != 8:
            raise pickle.UnpicklingError("FRAME past the end of the payload")
        (length,) = struct.unpack("<Q", header)
        if length > self._size - self._stream.tell():
            raise pickle.UnpicklingError(f"a frame of {length} bytes past the end of the payload")

    def _binget(self) -> None:
        # The most frequent opcode, so _resolving's check is inlined here rather than wrapped around it.
        index = self.read(1)[0]
        try:
            value = self.memo[index]
        except KeyError:
            raise pickle.UnpicklingError(f"Memo value not found at index {index}") from None
        if isinstance(value, _ArrayBuilder) and value.result is not None:
            value = value.result
        self.append(value)

    def _bytearray8(self) -> None:
        # The pure-Python unpickler allocates the claimed length before reading it.
        (length,) = struct.unpack("<Q", self.read(8))
        if length > self.reader.max_bytes:
            raise self.reader.refuse(f"a bytearray of {length} bytes in a payload of at most {self.reader.max_bytes}")
        data = self.read(length)
        if len(data) != length:
            raise pickle.UnpicklingError("BYTEARRAY8 past the end of the payload")
        self.append(bytearray(data))


def _resolving(handler: Callable[[Any], None]) -> Callable[[Any], None]:
    # A memo entry holds what _reconstruct returned; once built, a reference to it means the array.
    def run(self: _Unpickler) -> None:
        handler(self)
        top = self.stack[-1]
        if isinstance(top, _ArrayBuilder) and top.result is not None:
            self.stack[-1] = top.result
    return run


def _dispatch() -> _Dispatch:
    table: _Dispatch = dict(_PurePython.dispatch)
    table[pickle.BUILD[0]] = _Unpickler._build
    table[pickle.NEWOBJ[0]] = _Unpickler._newobj
    table[pickle.BYTEARRAY8[0]] = _Unpickler._bytearray8
    table[pickle.FRAME[0]] = _Unpickler._frame
    for code in (pickle.EXT1, pickle.EXT2, pickle.EXT4, pickle.INST, pickle.OBJ, pickle.NEWOBJ_EX):
        table[code[0]] = _Unpickler._refused
    for code in (pickle.GET, pickle.LONG_BINGET):
        table[code[0]] = _resolving(table[code[0]])
    table[pickle.BINGET[0]] = _Unpickler._binget
    return table


_Unpickler.dispatch = _dispatch()


# -- the result's shape -----------------------------------------------------------------------------

def _children(value: Any, reader: _Reader) -> list[Any]:
    if isinstance(value, list | tuple | set | frozenset):
        return list(value)
    if isinstance(value, dict):
        return [*value.keys(), *value.values()]
    names = reader.fields.get(type(value))
    if names is not None:
        state = vars(value)
        missing = names - state.keys()
        if missing:
            raise reader.refuse(f"a {type(value).__name__} without {sorted(missing)}")
        return list(state.values())
    if isinstance(value, _ArrayBuilder):
        raise reader.refuse("an array that was never built (numpy's _reconstruct without its data), or used "
                            "before it was")
    if isinstance(value, _DTypeSpec | _TorchStorage | _StorageType | _Marker):
        raise reader.refuse(f"a bare {type(value).__name__.strip('_')} where only values may be")
    return []


#: Exact types that hold no other values (_children yields nothing for them): not walked at all.
_LEAVES = frozenset({type(None), bool, int, float, complex, str, bytes, bytearray, np.ndarray})


def _check_result(root: Any, reader: _Reader) -> None:
    """No cycles, no nesting deeper than the limit, no half-built values; without recursion."""
    height: dict[int, int] = {}
    on_path: set[int] = set()
    # (value, its children that are not leaves once entered: None until then); a leaf's height is 0
    todo: list[tuple[Any, list[Any] | None]] = [(root, None)]
    max_depth = reader.limits.max_depth
    while todo:
        value, entered = todo.pop()
        key = id(value)
        if entered is not None:
            on_path.discard(key)
            depth = 1 + max((height.get(id(child), 0) for child in entered), default=0)
            if depth > max_depth:
                raise reader.refuse(f"nested deeper than {max_depth}")
            height[key] = depth
            continue
        children = _children(value, reader)
        if not children or key in height:
            continue
        if key in on_path:
            raise reader.refuse("the payload refers to itself (a cycle)")
        inner = [child for child in children if type(child) not in _LEAVES]
        if not inner:  # only leaves below: its height is 1, known without a second visit
            if max_depth < 1:
                raise reader.refuse(f"nested deeper than {max_depth}")
            height[key] = 1
            continue
        on_path.add(key)
        todo.append((value, inner))
        todo.extend((child, None) for child in inner)


def restricted_loads(data: bytes, allowed: Mapping[tuple[str, str], Any], *, max_bytes: int,
                     what: str = "pickled payload", limits: PayloadLimits | None = None) -> Any:
    """Unpickle ``data`` admitting only the globals in ``allowed``, within ``limits``.

    :param allowed: (module, name) as the payload spells it -> the object to use for it; dataclasses
        among the values may be created and have their fields set.
    :param max_bytes: a longer payload is refused before reading it.
    :param what: names the payload in errors ("LeRobot actions from host:port").
    :param limits: the array, depth and opcode budget (default :class:`PayloadLimits()`).
    :raises UnsafePayloadError: the payload breaks a rule of the module docstring.
    :raises ProtocolError: the bytes are not a valid pickle, or ``limits.check_array`` refused an array.
    """
    if len(data) > max_bytes:
        raise UnsafePayloadError(f"{what}: {len(data)} bytes, more than the {max_bytes} allowed")
    from .fast_pickle import DECLINED, fast_loads  # noqa: PLC0415  # the same rules at C speed, or DECLINED
    if (result := fast_loads(data, allowed, max_bytes=max_bytes, what=what, limits=limits or PayloadLimits())) \
            is not DECLINED:
        return result
    reader = _Reader(allowed, what, limits or PayloadLimits(), max_bytes)
    try:
        result = reader.load(data)
        _check_result(result, reader)
    except UnsafePayloadError as exc:
        if str(exc).startswith(what):
            raise
        raise UnsafePayloadError(f"{what}: {exc}") from None  # raised where the payload's name is not known
    except ProtocolError:
        raise
    except Exception as exc:  # anything a malformed pickle provokes (EOF, bad opcode, wrong argument types)
        raise ProtocolError(f"{what}: not a readable pickle: {type(exc).__name__}: {str(exc)[:200]}") from None
    return result
