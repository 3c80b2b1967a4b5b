"""What makes a Memory database safe to reopen: ours only, one writer, the same embedder, vectors kept with the rows.

Before the emem engine touches ``db_path`` (:func:`check_database_path`, :func:`claim`):

- the path must be a regular file or absent (a device such as ``/dev/null``, a folder or a pipe is
  refused untouched: SQLite never creates a ``-journal`` beside it);
- an existing SQLite file must be ours: its header's ``application_id`` is :data:`APPLICATION_ID`,
  or it holds the engine's tables (a database written before this mark existed, adopted). Any other
  file is refused untouched, read only through its header and a read-only look at its table names;
- one process writes a database: an OS lock (``flock``) on ``<db_path>.lock``, held while the
  engine is open, released by the kernel when the process dies (SIGKILL included). A second opener is
  refused with an error naming the process that holds it;
- the embedding model (its checkpoint) and dimension are kept in the database and compared at
  open: another model is refused (or, with ``on_embedding_change="reembed"``, every stored text is
  embedded again with the new one), never answered with vectors of another space.

Once the engine is open (:func:`store_class`, :func:`resync`): every vector added to the
engine's hnswlib index is also written, in the same SQLite transaction, to :data:`VECTOR_TABLE`;
the index file is written atomically (temporary file, fsync, rename) with its size and CRC-32
recorded in the database. At open, an index file whose size or CRC differ (damaged, torn) is set
aside as ``<index>.damaged`` and rebuilt from the rows; entries committed after the last save (a
crash) are added back from the rows, and texts without a stored vector are embedded again.
"""

from __future__ import annotations

import contextlib
import functools
import logging
import os
import sqlite3
import stat
import zlib
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any
from urllib.parse import quote

from .engine import MemoryStoreError

__all__ = ["APPLICATION_ID", "VECTOR_TABLE", "DatabaseLock", "check_database_path", "claim", "resync", "store_class"]

_logger = logging.getLogger(__name__)

#: SQLite ``application_id`` of a Memory database ("AGME").
APPLICATION_ID = 0x41474D45
#: Our key/value table: format, embedding model and dimension, the index file's size and CRC.
META_TABLE = "agents_core_memory"
#: The vector of every hnswlib entry, by the entry's integer id (float32, little-endian).
VECTOR_TABLE = "agents_core_vectors"
#: The tables the emem engine creates: a file holding all of them is an earlier Memory database.
ENGINE_TABLES = frozenset({"observations", "episodes", "gists", "edges", "entities", "hnsw_mappings"})
_OURS = ENGINE_TABLES | {META_TABLE, VECTOR_TABLE}
#: Where each kind of hnswlib entry keeps the text it was embedded from.
_TEXTS = {"observation": "SELECT text FROM observations WHERE id = ?", "gist": "SELECT text FROM gists WHERE id = ?",
          "entity": "SELECT name FROM entities WHERE id = ?", "episode": "SELECT gist FROM episodes WHERE id = ?"}
_CHUNK = 64


def _refuse(db_path: str, why: str) -> MemoryStoreError:
    return MemoryStoreError(f"cannot open the memory database {db_path!r}: {why}")


def _regular_or_absent(path: str, db_path: str, what: str) -> bool:
    """True if ``path`` is a regular file, False if absent; refuses anything else (nothing is created)."""
    try:
        mode = os.stat(path).st_mode
    except FileNotFoundError:
        return False
    except OSError as exc:
        raise _refuse(db_path, f"{what} {path!r}: {exc.strerror or exc}") from exc
    if not stat.S_ISREG(mode):
        raise _refuse(db_path, f"{what} {path!r} is not a regular file (a device, folder, pipe or socket): "
                               "refused, nothing written")
    return True


def check_database_path(db_path: str, index_path: str) -> str:
    """The database's path, resolved; MemoryStoreError (before anything is created) when it cannot be ours."""
    resolved = os.path.realpath(db_path)
    folder = os.path.dirname(resolved)
    if not os.path.isdir(folder):
        raise _refuse(db_path, f"its folder {folder!r} does not exist or is not a folder")
    for path, what in ((resolved, "the file"), (f"{resolved}-wal", "the file"), (f"{resolved}-journal", "the file"),
                       (f"{resolved}.lock", "the lock file"), (index_path, "the vector index")):
        _regular_or_absent(path, db_path, what)
    return resolved


class DatabaseLock:
    """An exclusive ``flock`` on ``<db_path>.lock`` naming its holder's PID; released by :meth:`release` or exit."""

    def __init__(self, db_path: str) -> None:
        self.db_path = db_path
        self.path = f"{db_path}.lock"
        self._fd: int | None = None

    def acquire(self) -> None:
        """Take the lock, or raise MemoryStoreError naming the process that holds it."""
        try:
            import fcntl  # noqa: PLC0415  (POSIX)
        except ImportError:  # pragma: no cover - not POSIX: no OS lock to take
            _logger.warning("no file locks on this system: one process per memory database is not enforced")
            return
        try:
            fd = os.open(self.path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC | os.O_NOFOLLOW, 0o644)
        except OSError as exc:
            raise _refuse(self.db_path, f"its lock file {self.path!r}: {exc.strerror or exc}") from exc
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            holder = os.pread(fd, 32, 0).decode("ascii", "replace").strip()
            os.close(fd)
            who = f"process {holder}" if holder.isdigit() else "another process"
            raise _refuse(self.db_path, f"it is in use by {who} (lock {self.path!r}): one process writes a "
                                        "memory database; give this Memory its own db_path") from None
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
        self._fd = fd

    def release(self) -> None:
        """Let the next process open the database (the lock file stays, empty of meaning)."""
        if self._fd is not None:
            with contextlib.suppress(OSError):
                os.ftruncate(self._fd, 0)
            os.close(self._fd)  # closing the descriptor drops the flock
            self._fd = None


def _table_names(db_path: str) -> set[str]:
    """The table names of an existing SQLite file, read without writing anything beside it."""
    wal = os.path.exists(f"{db_path}-wal")
    uri = f"file:{quote(db_path)}?mode=ro" + ("" if wal else "&immutable=1")
    try:
        conn = sqlite3.connect(uri, uri=True)
        try:
            return {row[0] for row in conn.execute("SELECT name FROM sqlite_master WHERE type = 'table'")}
        finally:
            conn.close()
    except sqlite3.Error as exc:
        raise _refuse(db_path, f"it cannot be read as a SQLite database ({exc}): refused, nothing written") from exc


def _kind(db_path: str) -> str:
    """``"new"``, ``"ours"`` or ``"earlier"`` (ours before the mark); MemoryStoreError for a foreign file."""
    try:
        with open(db_path, "rb") as f:
            header = f.read(100)
    except FileNotFoundError:
        return "new"
    if not header:
        return "new"
    if len(header) < 100 or not header.startswith(b"SQLite format 3\0"):
        raise _refuse(db_path, "it is not a SQLite database: refused, nothing written")
    application_id = int.from_bytes(header[68:72], "big")
    if application_id == APPLICATION_ID:
        return "ours"
    if application_id != 0:
        raise _refuse(db_path, f"it belongs to another application (SQLite application_id {application_id:#x}): "
                               "refused, nothing written")
    tables = _table_names(db_path)
    if not tables:
        return "new"
    if ENGINE_TABLES <= tables <= _OURS | {"sqlite_sequence", "sqlite_stat1"}:
        return "earlier"
    raise _refuse(db_path, f"it is not a memory database (its tables: {sorted(tables)[:8]}): refused, "
                           "nothing written")


def _index_file_dim(index_path: str) -> int | None:
    """The vector dimension an hnswlib index file declares in its header (None: unreadable)."""
    try:
        with open(index_path, "rb") as f:
            header = f.read(48)
    except OSError:
        return None
    if len(header) < 48:
        return None
    label_offset, offset_data = (int.from_bytes(header[i:i + 8], "little") for i in (32, 40))
    dim, rest = divmod(label_offset - offset_data, 4)
    return dim if dim > 0 and not rest else None


def claim(db_path: str, index_path: str, model: str, dim: int, reembed: bool) -> tuple[DatabaseLock, list[str]]:
    """Check, lock and mark the database before the engine opens it; the lock and what was done (for the log).

    :param model: the embedding model's identity (its checkpoint); :param dim: its vectors' length.
    :param reembed: another model than the database's: drop the stored vectors (every text is then
        embedded again by :func:`resync`) instead of refusing.
    """
    _kind(db_path)  # a foreign file is refused before the lock file is made beside it
    lock = DatabaseLock(db_path)
    lock.acquire()
    try:
        return lock, _mark(db_path, index_path, _kind(db_path), model, dim, reembed)
    except BaseException:
        lock.release()
        raise


def _mark(db_path: str, index_path: str, kind: str, model: str, dim: int, reembed: bool) -> list[str]:
    notes: list[str] = []
    try:
        conn = sqlite3.connect(db_path, isolation_level=None)
    except sqlite3.Error as exc:
        raise _refuse(db_path, f"{type(exc).__name__}: {exc}") from exc
    try:
        conn.execute("BEGIN IMMEDIATE")
        if kind != "ours":
            conn.execute(f"PRAGMA application_id = {APPLICATION_ID}")
        conn.execute(f"CREATE TABLE IF NOT EXISTS {META_TABLE} (key TEXT PRIMARY KEY, value TEXT NOT NULL)")
        conn.execute(f"CREATE TABLE IF NOT EXISTS {VECTOR_TABLE} (int_id INTEGER PRIMARY KEY, vector BLOB NOT NULL)")
        meta = dict(conn.execute(f"SELECT key, value FROM {META_TABLE}").fetchall())
        if kind == "earlier" and "embedding_dim" not in meta:
            old_dim = _index_file_dim(index_path) if os.path.exists(index_path) else None
            if old_dim is not None:
                meta["embedding_dim"] = str(old_dim)
            notes.append("a database of an earlier version: marked as a memory database")
        old = (meta.get("embedding_model"), meta.get("embedding_dim"))
        if (old[0] is not None and old[0] != model) or (old[1] is not None and old[1] != str(dim)):
            described = f"{old[0] or 'an unrecorded model'!r} ({old[1] or '?'} dimensions)"
            if not reembed:
                raise _refuse(db_path, f"it was written with the embedding model {described} and this Memory's "
                                       f"embedding_client gives {model!r} ({dim} dimensions): its answers would "
                                       "be wrong. Use the same model, another db_path, or "
                                       "on_embedding_change='reembed'")
            conn.execute(f"DELETE FROM {VECTOR_TABLE}")
            conn.execute(f"DELETE FROM {META_TABLE} WHERE key = 'index_digest'")
            _set_aside(index_path, ".replaced")
            notes.append(f"written with {described}: every text is embedded again with {model!r}")
        for key, value in (("format", "1"), ("embedding_model", model), ("embedding_dim", str(dim))):
            conn.execute(f"INSERT OR REPLACE INTO {META_TABLE} (key, value) VALUES (?, ?)", (key, value))
        digest = meta.get("index_digest")
        if os.path.exists(index_path) and digest is not None and digest != _digest(index_path):
            _set_aside(index_path, ".damaged")
            notes.append(f"the vector index {index_path!r} was damaged (set aside as .damaged): rebuilt from the rows")
        conn.execute("COMMIT")
        if kind == "earlier":
            conn.execute("PRAGMA wal_checkpoint(TRUNCATE)")  # the mark into the file's header
    except sqlite3.Error as exc:
        raise _refuse(db_path, f"{type(exc).__name__}: {exc}") from exc
    finally:
        conn.close()
    for stale in Path(index_path).parent.glob(f"{Path(index_path).name}.*.tmp"):
        with contextlib.suppress(OSError):
            stale.unlink()  # a save that a crash interrupted
    return notes


def _set_aside(index_path: str, suffix: str) -> None:
    if os.path.exists(index_path):
        os.replace(index_path, index_path + suffix)


def _digest(path: str) -> str:
    crc, size = 0, 0
    with open(path, "rb") as f:
        while chunk := f.read(1 << 20):
            crc, size = zlib.crc32(chunk, crc), size + len(chunk)
    return f"{size}:{crc:08x}"


def _fsync_folder(folder: Path) -> None:
    with contextlib.suppress(OSError):
        fd = os.open(folder, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


def _store_class() -> type:
    from emem.store import MemoryStore  # noqa: PLC0415  (the optional engine)

    class _Durable(MemoryStore):  # type: ignore[misc]
        """emem's store whose vectors are also rows, and whose index file is written atomically."""

        def _add_to_hnsw(self, str_id: str, embedding: Any, node_type: str = "observation") -> None:
            import numpy as np  # noqa: PLC0415

            vector = np.asarray(embedding, dtype="<f4").reshape(-1)
            super()._add_to_hnsw(str_id, vector, node_type)
            self._db.execute(f"INSERT OR REPLACE INTO {VECTOR_TABLE} (int_id, vector) VALUES (?, ?)",
                             (self._hnsw_str_map[str_id], vector.tobytes()))

        def _remove_from_hnsw(self, str_id: str) -> None:
            int_id = self._hnsw_str_map.get(str_id)
            super()._remove_from_hnsw(str_id)
            if int_id is not None:
                self._db.execute(f"DELETE FROM {VECTOR_TABLE} WHERE int_id = ?", (int_id,))

        def reload_mappings(self) -> None:
            """Read the index's id mappings from the rows again (emem reads them only when the index file exists)."""
            self._hnsw_id_map.clear()
            self._hnsw_str_map.clear()
            self._hnsw_counter = 0
            self._load_hnsw_mappings()

        def save(self) -> None:
            path = Path(self._hnsw_path)
            temporary = path.with_name(f"{path.name}.{os.getpid()}.tmp")
            try:
                self._hnsw.save_index(str(temporary))
                with open(temporary, "rb") as f:
                    os.fsync(f.fileno())
                digest = _digest(str(temporary))
                os.replace(temporary, path)
            finally:
                with contextlib.suppress(FileNotFoundError):
                    temporary.unlink()
            _fsync_folder(path.parent)
            self._db.execute(f"INSERT OR REPLACE INTO {META_TABLE} (key, value) VALUES ('index_digest', ?)",
                             (digest,))
            self._db.commit()

    return _Durable


#: emem's ``MemoryStore`` with vectors kept as rows and atomic index saves (made once, on first use).
store_class: Callable[[], type] = functools.cache(_store_class)


def _chunks(items: list[int]) -> Iterable[list[int]]:
    for start in range(0, len(items), 4096):
        yield items[start:start + 4096]


def resync(store: Any, embed: Callable[[list[str]], Any]) -> list[str]:
    """Bring ``store``'s in-memory index in line with its committed rows; what was done (for the log).

    Entries whose rows were committed after the index file was saved are added from their stored
    vectors (or their texts embedded again); entries of the file without rows are marked deleted;
    vectors of an earlier database are copied into :data:`VECTOR_TABLE`. Saves the index if anything changed.
    """
    import numpy as np  # noqa: PLC0415

    store.reload_mappings()
    wanted = set(store._hnsw_id_map)
    held = {int(i) for i in store._hnsw.get_ids_list()}
    notes: list[str] = []
    stray = []
    for label in sorted(held - wanted):
        with contextlib.suppress(RuntimeError):  # already marked deleted: nothing to do
            store._hnsw.mark_deleted(label)
            stray.append(label)
    kept = {row[0] for row in store._db.execute(f"SELECT int_id FROM {VECTOR_TABLE}")}
    backfill = sorted((wanted & held) - kept)
    for part in _chunks(backfill):
        vectors = np.asarray(store._hnsw.get_items(part), dtype="<f4")
        store._db.executemany(f"INSERT OR REPLACE INTO {VECTOR_TABLE} (int_id, vector) VALUES (?, ?)",
                              [(i, v.tobytes()) for i, v in zip(part, vectors, strict=True)])
    missing = sorted(wanted - held)
    restored, embedded, lost = _restore(store, missing, embed)
    if restored:
        notes.append(f"{restored} entr{'y' if restored == 1 else 'ies'} committed after the last index save "
                     "added back from the rows")
    if embedded:
        notes.append(f"{embedded} text(s) without a stored vector embedded again")
    if lost:
        notes.append(f"{lost} index entr{'y' if lost == 1 else 'ies'} without a vector or a text: not findable "
                     "by meaning")
    if stray:
        notes.append(f"{len(stray)} index entr{'y' if len(stray) == 1 else 'ies'} without rows removed")
    store._db.commit()
    if backfill or missing or stray:
        store.save()
    return notes


def _restore(store: Any, missing: list[int], embed: Callable[[list[str]], Any]) -> tuple[int, int, int]:
    """Add the entries ``missing`` from the index from their stored vectors, or their texts embedded again;
    how many were restored, embedded, and neither."""
    import numpy as np  # noqa: PLC0415

    dim = int(store._hnsw.dim)
    restored, embedded, lost = 0, 0, 0
    for part in _chunks(missing):
        rows = dict(store._db.execute(f"SELECT int_id, vector FROM {VECTOR_TABLE} WHERE int_id IN "
                                      f"({','.join('?' * len(part))})", part).fetchall())
        ids, vectors = [], []
        for int_id in part:
            blob = rows.get(int_id)
            if isinstance(blob, bytes) and len(blob) == 4 * dim:
                ids.append(int_id)
                vectors.append(np.frombuffer(blob, dtype="<f4"))
        restored += len(ids)
        found = set(ids)
        texts = _texts(store, [i for i in part if i not in found])
        lost += len(part) - len(ids) - len(texts)
        for start in range(0, len(texts), _CHUNK):
            batch = texts[start:start + _CHUNK]
            fresh = np.asarray(embed([t for _, t in batch]), dtype="<f4")
            usable = np.isfinite(fresh).all(axis=1) & (np.abs(fresh).sum(axis=1) > 0)
            lost += int((~usable).sum())
            batch, fresh = [b for b, ok in zip(batch, usable, strict=True) if ok], fresh[usable]
            store._db.executemany(f"INSERT OR REPLACE INTO {VECTOR_TABLE} (int_id, vector) VALUES (?, ?)",
                                  [(i, v.tobytes()) for (i, _), v in zip(batch, fresh, strict=True)])
            ids += [i for i, _ in batch]
            vectors += list(fresh)
            embedded += len(batch)
        if ids:
            need = store._hnsw.get_current_count() + len(ids) + 1
            if need >= store._hnsw.get_max_elements():
                store._hnsw.resize_index(need + store.config.hnsw_max_elements)
            store._hnsw.add_items(np.vstack(vectors), np.asarray(ids))
    return restored, embedded, lost


def _texts(store: Any, int_ids: list[int]) -> list[tuple[int, str]]:
    found = []
    for int_id in int_ids:
        row = store._db.execute("SELECT str_id, node_type FROM hnsw_mappings WHERE int_id = ?", (int_id,)).fetchone()
        query = _TEXTS.get(row[1]) if row is not None else None
        text = store._db.execute(query, (row[0],)).fetchone() if query is not None else None
        if text is not None and isinstance(text[0], str) and text[0].strip():
            found.append((int_id, text[0]))
    return found
