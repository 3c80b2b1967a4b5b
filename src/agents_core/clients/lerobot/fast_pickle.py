"""The restricted reader's fast path: the same rules, with the opcodes run by Python's C unpickler.

:func:`~agents_core.clients.lerobot.restricted_pickle.restricted_loads` tries this first. It either
returns a result the full reader would return too (one exception, below), or *declines* (:data:`DECLINED`), and the full
(pure-Python) reader then reads the payload and gives the verdict. Declining costs one extra read of a
payload that is hostile or unusual. It accepts nothing the full reader's rules would not let through
as a value, with one difference of order: an array handed to a payload class before its BUILD (which
the full reader refuses) is accepted, and still checked in full when it is built.

How the rules hold without the pure-Python opcode loop:

- one pass over the opcode stream first (:func:`scan`) counts the opcodes against the budget and
  declines anything the C unpickler would act on before a rule could look at it: a memo index beyond
  the opcodes seen so far (the C unpickler grows its memo table to the index), a counted length past
  the end of the payload (it allocates the length first), and the opcodes the full reader refuses or
  treats specially (extension registry, INST/OBJ, NEWOBJ_EX, out-of-band buffers, text persistent ids);
- ``find_class`` (the documented way to restrict a C unpickler's globals) consults the same allow-list,
  and hands out nothing BUILD could change for the process: functions come wrapped in :class:`_Call`
  (immutable, BUILD refused), payload classes as a sealed subclass per class (class attributes cannot be
  set; ``__new__`` takes no arguments; BUILD sets only declared fields), and numpy's and torch's
  stand-ins as per-payload objects whose BUILD is the full reader's own check;
- after loading, one walk swaps each built array in for its builder (in lists, dicts and payload objects;
  anywhere else it declines), gives payload objects their real class back, and the full reader's
  result check (depth, cycles, half-built values) runs on the result.
"""

from __future__ import annotations

import io
import pickle
import re
import struct
from collections.abc import Callable, Mapping
from dataclasses import replace
from typing import Any, cast

import numpy as np

from ...errors import ProtocolError
from . import restricted_pickle as rp

__all__ = ["DECLINED", "fast_loads", "scan"]

#: What :func:`fast_loads` returns when the full reader must read the payload.
DECLINED: Any = object()


class _Declined(Exception):
    """The fast path cannot vouch for this payload; the full reader decides."""


def _arg_kinds() -> list[int]:
    # >= 0: a fixed argument length; -1/-4/-8: a 1/4/8-byte length first; -10: one line; -11: two
    # lines; -12: a memo index (checked); -13: declined.
    kinds = [-13] * 256
    for plain in (b"(.01", b"2NRabd}el]stu)Q", b"\x81\x85\x86\x87\x88\x89\x8f\x90\x91\x93\x94"):
        for op in plain:
            kinds[op] = 0
    for fixed, size in ((b"J", 4), (b"K", 1), (b"M", 2), (b"G", 8), (b"h", 1), (b"j", 4), (b"q", 1), (b"\x80", 1)):
        kinds[fixed[0]] = size
    for ops, kind in ((b"CU\x8c\x8a", -1), (b"BXT\x8b", -4), (b"\x8e\x8d\x96", -8), (b"ILFSVg", -10),
                      (b"c", -11), (b"rp\x95", -12)):
        for op in ops:
            kinds[op] = kind
    return kinds


_KINDS = _arg_kinds()
_STOP = pickle.STOP[0]
#: A run of opcodes with a fixed argument length (STOP excepted), matched by the regex engine in one
#: call: where the payload has no more bytes than opcodes left in the budget, nothing needs counting.
_RUN = re.compile(b"(?:[" + re.escape(bytes(op for op in range(256) if _KINDS[op] == 0 and op != _STOP)) + b"]"
                  + b"|[" + re.escape(bytes(op for op in range(256) if _KINDS[op] == 1)) + b"].|M..|[Jj]....|G.{8})*+",
                  re.DOTALL)


def scan(data: bytes, start: int, ops_left: int) -> tuple[int, int]:
    """The end of the pickle at ``start`` in ``data`` and its opcode count; declines (raises) past
    ``ops_left`` opcodes, on an opcode the fast path leaves to the full reader, on a length or frame
    past the end and on a memo index beyond the opcodes seen."""
    kinds, end, i, ops = _KINDS, len(data), start, 0
    unpack = struct.unpack_from
    # Every opcode is at least a byte: with no more bytes than opcodes left, runs need no counting
    # (the count returned is then the bytes read, a bound), and a memo index is bounded by the position.
    run = _RUN.match if end - start <= ops_left else None
    try:
        while True:
            if run is not None:
                i = run(data, i).end()  # type: ignore[union-attr]  # the pattern matches the empty run
                ops = i - start
            op = data[i]
            kind = kinds[op]
            i += 1
            ops += 1
            if kind >= 0:
                i += kind
                if op == _STOP and ops <= ops_left:
                    return i, ops
            elif kind == -1:
                i += 1 + data[i]
            elif kind == -4:
                i += 4 + unpack("<I", data, i)[0]  # a negative signed length: past the end
            elif kind == -8:
                i += 8 + unpack("<Q", data, i)[0]
            elif kind == -10:
                i = data.index(b"\n", i) + 1
            elif kind == -11:
                i = data.index(b"\n", data.index(b"\n", i) + 1) + 1
            elif kind == -12:
                if op == 0x95:  # FRAME: only a length, checked like the others
                    i += 8
                    if unpack("<Q", data, i - 8)[0] > end - i:
                        raise _Declined
                    continue
                if op == 0x72:  # LONG_BINPUT
                    index, i = unpack("<I", data, i)[0], i + 4
                else:  # PUT
                    line_end = data.index(b"\n", i)
                    index, i = int(data[i:line_end]), line_end + 1
                if index > ops:
                    raise _Declined
            else:
                raise _Declined
            if i > end or ops > ops_left or i < start:
                raise _Declined
    except (IndexError, ValueError, struct.error):
        raise _Declined from None


# -- what find_class hands out ----------------------------------------------------------------------

class _Call:
    """An allow-listed function (or class called by REDUCE), bound to the reader where it needs one."""

    __slots__ = ("_function", "_reader")
    _function: Callable[..., Any]
    _reader: rp._Reader | None

    def __init__(self, function: Callable[..., Any], reader: rp._Reader | None = None) -> None:
        object.__setattr__(self, "_function", function)
        object.__setattr__(self, "_reader", reader)

    def __call__(self, *args: Any) -> Any:
        if self._reader is None:
            return self._function(*args)
        return self._function(self._reader, *args)

    def __setattr__(self, name: str, value: Any) -> None:
        raise rp.UnsafePayloadError("a payload may not set attributes of a global")

    def __setstate__(self, state: Any) -> None:
        raise rp.UnsafePayloadError("BUILD on a global; refused")


class _SealedMeta(type):
    """The type of a payload class's sealed stand-in: its attributes cannot be set or deleted."""

    def __setattr__(cls, name: str, value: Any) -> None:
        raise rp.UnsafePayloadError(f"a payload may not set {name!r} on a class")

    def __delattr__(cls, name: str) -> None:
        raise rp.UnsafePayloadError(f"a payload may not delete {name!r} from a class")

    def __call__(cls, *args: Any, **kwargs: Any) -> Any:
        # REDUCE calls the class (its __init__ takes the arguments); NEWOBJ goes to __new__ directly.
        made: Any = object.__new__(cast(type, cls))
        made.__init__(*args, **kwargs)
        return made


def _sealed_new(cls: type, *args: Any, **kwargs: Any) -> Any:
    if args or kwargs:
        raise rp.UnsafePayloadError("a payload class is created without arguments")
    return object.__new__(cls)


def _sealed_setstate(self: Any, state: Any) -> None:
    names = type(self)._fields  # the real class's declared fields (only a str equals one of them)
    if type(state) is not dict or not state.keys() <= names:
        raise rp.UnsafePayloadError(f"BUILD of a {type(self).__name__} with fields other than {sorted(names)}")
    vars(self).update(state)


_SEALED: dict[type, type] = {}


def _sealed(cls: type, names: frozenset[str]) -> type:
    sealed = _SEALED.get(cls)
    if sealed is None:
        sealed = _SealedMeta(cls.__name__, (cls,), {"__slots__": (), "__new__": _sealed_new,
                                                    "__setstate__": _sealed_setstate, "_fields": names,
                                                    "_real": cls, "__module__": cls.__module__})
        _SEALED[cls] = sealed
    return sealed


class _FastDType(rp._DTypeSpec):
    __slots__ = ()

    def __setstate__(self, state: Any) -> None:
        self.build(state)


class _FastBuilder(rp._ArrayBuilder):
    __slots__ = ("reader",)

    def __init__(self, reader: rp._Reader) -> None:
        super().__init__()
        self.reader = reader

    def __setstate__(self, state: Any) -> None:
        # numpy's (version, shape, dtype, is_fortran, rawdata) of a 1-D array, checked here as
        # build_array checks it (one Python call instead of four); any other state goes there.
        if (type(state) is tuple and len(state) == 5 and state[0] == 1 and type(state[1]) is tuple
                and len(state[1]) == 1 and type(state[1][0]) is int and state[1][0] >= 0
                and type(state[2]) is _FastDType and state[3] is False and type(state[4]) is bytes
                and self.result is None):
            shape, spec, raw = state[1], state[2], state[4]
            count = self.reader.charge(shape, spec.native())
            if len(raw) != count * spec.itemsize:
                raise rp.UnsafePayloadError(f"array data of {len(raw)} bytes for shape {shape} of {spec.code!r}")
            self.result = np.frombuffer(raw, dtype=spec.wire(), count=count).astype(spec.native())
        else:
            self.reader.build_array(self, state)


class _FastMarker(rp._Marker):

    def __setstate__(self, state: Any) -> None:
        raise rp.UnsafePayloadError("BUILD on numpy.ndarray; refused")


_FAST_NDARRAY = _FastMarker("numpy.ndarray")


class _FastStorageType(rp._StorageType):
    def __setstate__(self, state: Any) -> None:
        raise rp.UnsafePayloadError("BUILD on a torch storage type; refused")


class _FastTorchStorage(rp._TorchStorage):
    """What ``_load_from_bytes`` gives on the fast path: the C unpickler's BUILD on a frozen dataclass
    would write its state into ``__dict__`` (a 2-D ``flat``, whose ``size`` bound lets a tensor read past
    it); the full reader refuses that BUILD, and so does this."""

    def __setstate__(self, state: Any) -> None:
        raise rp.UnsafePayloadError("BUILD on a torch storage; refused")


def _fast_load_torch_storage(reader: rp._Reader, data: Any) -> _FastTorchStorage:
    return _FastTorchStorage(rp._load_torch_storage(reader, data).flat)


def _fast_reconstruct(reader: rp._Reader, subtype: Any, shape: Any, typecode: Any) -> _FastBuilder:
    if subtype is not _FAST_NDARRAY:
        raise rp.UnsafePayloadError("_reconstruct of something other than numpy.ndarray; refused")
    return _FastBuilder(reader)


def _hand_out(value: Any, reader: rp._Reader) -> Any:
    """What ``find_class`` returns for an allow-listed ``value``."""
    if isinstance(value, rp._ReaderFunction):
        if value.function is rp._load_torch_storage:
            return _Call(_fast_load_torch_storage, reader)
        return _Call(value.function, reader)
    if value is rp._reconstruct:
        return _Call(_fast_reconstruct, reader)
    if value is rp._DTypeSpec:
        return _Call(_FastDType)
    if value is rp._NDARRAY:
        return _FAST_NDARRAY
    if type(value) is rp._StorageType:
        return _FastStorageType(value.code)
    names = reader.fields.get(value) if isinstance(value, type) else None
    if names is not None:
        return _sealed(value, names)
    if callable(value) and not isinstance(value, rp._Marker):
        return _Call(value)
    raise _Declined


class _FastUnpickler(pickle.Unpickler):
    def __init__(self, stream: io.BytesIO, reader: _FastReader, allowed: Mapping[tuple[str, str], Any],
                 storage_ids: bool) -> None:
        super().__init__(stream)
        self.reader, self.allowed, self.storage_ids = reader, allowed, storage_ids

    def find_class(self, module: str, name: str) -> Any:
        try:
            value = self.allowed[(module, name)]
        except (KeyError, TypeError):
            raise _Declined from None
        return _hand_out(value, self.reader)

    def persistent_load(self, pid: Any) -> Any:
        if not self.storage_ids:
            raise _Declined
        return pid  # a torch storage's id tuple, checked by _load_torch_storage


class _FastReader(rp._Reader):
    """The full reader's budget and array checks, with nested pickles read by the C unpickler too."""

    _stream: io.BytesIO | None = None
    _data = b""

    def run(self, data: bytes, stream: io.BytesIO, allowed: Mapping[tuple[str, str], Any],
            storage_ids: bool) -> Any:
        start = stream.tell()
        end, ops = scan(data, start, self.ops_left)
        self.ops_left -= ops
        result = _FastUnpickler(stream, self, allowed, storage_ids).load()
        if stream.tell() != end:
            raise _Declined
        return result

    def load(self, data: bytes) -> Any:
        return self.run(data, io.BytesIO(data), self.allowed, False)

    def nested(self, stream: io.BytesIO, *, storage_ids: bool = False) -> Any:
        if stream is not self._stream:
            self._stream, self._data = stream, stream.getvalue()
        return self.run(self._data, stream, rp._STORAGE_GLOBALS, storage_ids)


def _settle(root: Any) -> Any:
    """Built arrays in for their builders, payload objects back to their real class; declines where a
    builder sits in something immutable (a tuple, a set, a dict key)."""
    seen: set[int] = set()
    todo = [root]

    def resolved(value: Any) -> Any:
        kind = type(value)
        if kind is _FastBuilder:
            if value.result is None:
                raise _Declined
            return value.result
        if kind is _Call or kind is _SealedMeta:  # a bare global where only values may be
            raise _Declined
        if type(kind) is _SealedMeta:
            object.__setattr__(value, "__class__", type(value)._real)
        todo.append(value)
        return value

    root = resolved(root)
    while todo:
        value = todo.pop()
        if id(value) in seen:
            continue
        seen.add(id(value))
        if isinstance(value, list):
            for index, item in enumerate(value):
                value[index] = resolved(item)
        elif isinstance(value, dict):
            if getattr(value, "__dict__", None):  # an OrderedDict given attributes by BUILD (the full reader
                raise _Declined                     # refuses BUILD on it; the C unpickler sets its __dict__)
            for key, item in value.items():
                if type(key) is _FastBuilder:
                    raise _Declined
                resolved(key)
                value[key] = resolved(item)
        elif isinstance(value, tuple | set | frozenset):
            for item in value:
                if type(item) is _FastBuilder:
                    raise _Declined
                resolved(item)
        elif hasattr(value, "__dict__") and not isinstance(value, type):
            state = vars(value)
            for key, item in state.items():
                state[key] = resolved(item)
    return root


def _flat_chunk(root: Any, reader: rp._Reader) -> bool:
    """Settles and checks a list of payload objects whose fields hold only leaves and arrays (a chunk of
    actions, depth 2) in one pass; False for anything else (then :func:`_settle` and the full check)."""
    if type(root) is not list or reader.limits.max_depth < 2:
        return False
    leaves = rp._LEAVES
    for item in root:
        sealed = type(item)
        if type(sealed) is not _SealedMeta:
            return False
        state = cast("dict[str, Any]", vars(item))
        if state.keys() != sealed._fields:  # every declared field set (BUILD allowed no others)
            return False
        for key, value in state.items():
            if type(value) is _FastBuilder:
                if value.result is None:
                    return False
                state[key] = value.result
            elif type(value) not in leaves:
                return False
        object.__setattr__(item, "__class__", sealed._real)
    return True


def fast_loads(data: bytes, allowed: Mapping[tuple[str, str], Any], *, max_bytes: int, what: str,
               limits: rp.PayloadLimits) -> Any:
    """``data`` read under the rules of :func:`~agents_core.clients.lerobot.restricted_pickle.restricted_loads`,
    or :data:`DECLINED` when the full reader must read it (a hostile payload, a form this path does not
    handle, any error). ``limits.check_array`` may then see an array twice (here and in the full reader);
    the :class:`~agents_core.errors.ProtocolError` it raises is raised at once."""
    # A caller's shape check may keep state (the first action's width): one it refused is final
    # (the full reader would present it the same shapes in the same order), not asked again.
    refused: list[ProtocolError] = []
    if limits.check_array is not None:
        check = limits.check_array

        def checked(shape: tuple[int, ...], dtype: np.dtype[Any]) -> None:
            try:
                check(shape, dtype)
            except ProtocolError as exc:
                refused.append(exc)
                raise
        limits = replace(limits, check_array=checked)
    reader = _FastReader(allowed, what, limits, max_bytes)
    try:
        result = reader.load(data)
        if not _flat_chunk(result, reader):
            result = _settle(result)
            rp._check_result(result, reader)
    except Exception:  # any other refusal or error: the full reader gives the verdict and the message
        if refused:
            raise refused[0] from None
        return DECLINED
    return result
