"""A chunk of actions exactly as LeRobot's policy server pickles it (its ``TimedAction`` dataclass, a torch
tensor row per action, plain ``pickle.dumps``) is read by the restricted reader's fast path, without torch,
to the same values as the full reader and as torch itself."""

from __future__ import annotations

import pickle

import numpy as np
import pytest

torch = pytest.importorskip("torch", reason="nox -s lerobot")
helpers = pytest.importorskip("lerobot.async_inference.helpers", reason="nox -s lerobot")

from agents_core.clients.lerobot import fast_pickle as fp  # noqa: E402
from agents_core.clients.lerobot import protocol as wire  # noqa: E402
from agents_core.clients.lerobot import restricted_pickle as rp  # noqa: E402


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_lerobots_own_chunk_reads_on_the_fast_path_as_the_full_reader_and_torch_read_it(dtype: object) -> None:
    chunk = torch.arange(50 * 6, dtype=dtype).reshape(50, 6) / 7  # type: ignore[call-overload]
    data = pickle.dumps([helpers.TimedAction(timestamp=0.5 + i, timestep=i, action=chunk[i]) for i in range(50)])
    fast = fp.fast_loads(data, wire._ALLOWED, max_bytes=1 << 24, what="t", limits=rp.PayloadLimits())
    assert fast is not fp.DECLINED
    reader = rp._Reader(wire._ALLOWED, "t", rp.PayloadLimits(), 1 << 24)
    full = reader.load(data)
    rp._check_result(full, reader)
    by_torch = pickle.loads(data)
    assert [type(a) for a in fast] == [wire.TimedAction] * 50
    for i, (a, b, c) in enumerate(zip(fast, full, by_torch, strict=True)):
        assert a.timestep == b.timestep == c.timestep == i and a.timestamp == b.timestamp == c.timestamp
        assert a.action.dtype == b.action.dtype and a.action.flags.writeable
        assert np.array_equal(a.action, b.action) and np.array_equal(a.action, c.action.numpy())
