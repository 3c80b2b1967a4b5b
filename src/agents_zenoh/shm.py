"""Shared memory for large values between processes on one host (the Zenoh driver's publishing side).

Two levels, both set in :class:`~agents_zenoh.config.ZenohConfig`:

- ``shared_memory`` (on by default, as in Zenoh): the session's shared-memory transport. Zenoh
  copies a payload above 3 KB into a shared-memory segment and hands a peer on the same host a
  reference to it (its "transport optimisation"); False (``transport/shared_memory/enabled``)
  sends everything over the network path instead.
- ``shm_threshold`` (None by default): a payload of that many bytes or more is written once into
  a block of a pool of the transport's own (:class:`ShmPool`, created on the first large value)
  and put as that block, which skips Zenoh's copy into its segment. It measured no better than
  the transport alone here (``benchmarks/shm.py``, see ``benchmarks/README.md``), hence off.

Either way, a peer on another host, or one whose shared memory is off, gets the bytes over the
network: Zenoh copies the block into the message for it, so nothing changes for the receiver.

What is copied, and the lifetime rule:

- publishing from the pool: the encoded payload is copied once into the block (zenoh-python's
  ``ZShmMut`` takes bytes by slice assignment; it exports no buffer a codec could write into).
- receiving: zenoh-python 1.10 gives no buffer view of a received block (``ZShm`` / ``ZBytes``
  do not export the buffer protocol), so the subscriber copies the payload out once
  (``to_bytes``) and the decoded arrays are numpy views of that private copy. **A value kept past
  the callback is therefore a copy, never a view of the shared block**: the block goes back to
  the publisher as soon as the sample is dropped, and nothing a publisher writes later can show
  through a kept value (``tests/agents_zenoh/test_shm.py`` checks it with a pool reused 3 times).
- a block is never written twice while in use: each value gets a fresh allocation, and Zenoh
  frees a block only when every receiver has dropped it. When the pool is full (slow receivers
  holding blocks) it collects and defragments, then the value takes the ordinary path.
"""

from __future__ import annotations

import logging
import sys
import threading
from collections.abc import Callable
from typing import Any

import zenoh

__all__ = ["NEVER", "ShmPool", "shm_payload", "shm_session_options"]

logger = logging.getLogger(__name__)

#: Threshold meaning "never": publishers compare a payload's length against it.
NEVER = sys.maxsize


def shm_session_options(enabled: bool) -> dict[str, Any]:
    """The Zenoh config settings for ``shared_memory=enabled`` (key path -> value)."""
    return {"transport/shared_memory/enabled": enabled}


class ShmPool:
    """A shared-memory provider of ``size`` bytes, created on first use, from which large payloads are put.

    :param size: the pool's size in bytes.
    :param threshold: payloads this large or larger are put from the pool (see :attr:`threshold`).
    """

    def __init__(self, size: int, threshold: int) -> None:
        self._size = size
        self._threshold = threshold
        self._provider: Any = None
        self._lock = threading.Lock()
        self._policy: Any = None
        self._broken = False
        #: Values put from the pool, and values that fell back to the network path (pool full or too large).
        self.shared = 0
        self.fallbacks = 0

    @property
    def threshold(self) -> int:
        """The smallest payload put from shared memory (:data:`NEVER` once the pool could not be created)."""
        return NEVER if self._broken else self._threshold

    def _open(self) -> Any:
        with self._lock:
            if self._provider is None and not self._broken:
                try:
                    from zenoh import shm  # noqa: PLC0415  (a zenoh built without shared memory lacks it)

                    self._provider = shm.ShmProvider.default_backend(self._size)
                    # Try; else collect the blocks receivers have dropped and try; else defragment and try.
                    self._policy = shm.GarbageCollect(shm.JustAlloc(), shm.Defragment())
                except (ImportError, zenoh.ZError) as exc:
                    logger.warning("Zenoh shared memory is unavailable (%s): large values take the network path",
                                   exc)
                    self._broken = True
            return self._provider

    def payload(self, data: bytes | bytearray) -> Any:
        """``data`` in a fresh shared-memory block as a ``ZBytes``, or ``data`` itself when no block is free."""
        provider = self._provider or self._open()
        if provider is None:
            return data
        size = len(data)
        try:
            block = provider.alloc(size, self._policy)
        except zenoh.ZError:
            self.fallbacks += 1
            return data
        block[0:size] = data
        self.shared += 1
        return zenoh.ZBytes(block)


def _unchanged(data: bytes | bytearray) -> Any:
    return data


def shm_payload(pool: ShmPool | None) -> tuple[int, Callable[[bytes | bytearray], Any]]:
    """(threshold, wrap) for a publisher: a payload of ``threshold`` bytes or more is put as ``wrap(payload)``
    (from ``pool``, the context's); without a pool the threshold is :data:`NEVER`."""
    if pool is None:
        return NEVER, _unchanged
    return pool.threshold, pool.payload
