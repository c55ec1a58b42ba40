"""Atomic writes and advisory locks: the primitives behind every output egs-bench writes.

* :func:`atomic_path` writes one file (or a small folder) under a hidden temporary name next to
  the target and renames it into place, so a crash or Ctrl-C never leaves a half-written file
  under the final name. It never replaces a directory with a file, a file with a directory, or a
  non-empty directory.
* :func:`atomic_dir` builds a whole folder (a generated sequence) in a hidden staging folder and
  renames it into place; with ``replace=True`` an existing folder is swapped out *after* the new
  one is complete and only then deleted. Staging folders carry an owner lock, so a staging folder
  left behind by a killed process (SIGKILL, power loss) is recognised and removed by the next
  write of the same target.
* :class:`FileLock` is an exclusive ``flock`` on a file; the kernel drops it when its process
  dies, however it dies, which is what makes stale run folders and staging folders detectable.

What may be replaced at all (``--overwrite`` rules) is decided by :mod:`egs_bench.outputs`.
:func:`read_text` is the one way text inputs are read, so a binary or unreadable file is always
reported as an :class:`~egs_bench.errors.InputError` naming it.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import os
import re
import shutil
import socket
import tempfile
import time
import uuid
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from egs_bench.errors import InputError, OutputError, UnwritableOutputError
from egs_bench.interrupts import raise_if_interrupted

#: a staging folder without an owner lock file older than this is considered abandoned
_STAGING_GRACE_S = 60.0
_OWNER_FILE = ".owner"

#: what every writer says when the file system has no room left (errno ENOSPC or EDQUOT)
DISK_FULL = "cannot write: the disk is full (no space left on device)"
_DISK_FULL_ERRNOS = frozenset({errno.ENOSPC, errno.EDQUOT})


def is_disk_full(exc: BaseException) -> bool:
    """Whether ``exc``, or an exception in its cause/context chain, is a file system without
    room (``ENOSPC``, or ``EDQUOT`` for a full quota). HDF5 reports the errno only in its
    message text (``errno = 28``)."""
    seen: set[int] = set()
    e: BaseException | None = exc
    while e is not None and id(e) not in seen:
        seen.add(id(e))
        if isinstance(e, OSError) and (e.errno in _DISK_FULL_ERRNOS
                                       or "errno = 28," in str(e)):
            return True
        e = e.__cause__ or e.__context__
    return False


@contextlib.contextmanager
def naming_full_disk(path: str | Path, *, outermost: bool = False) -> Iterator[None]:
    """Report a full disk met inside the block as an :class:`UnwritableOutputError` naming
    ``path`` (the output being written), instead of an ``OSError`` that names no file.

    Args:
        path: the output the block writes.
        outermost: also rename a full disk already reported for a file inside ``path``'s
            hidden staging folder, which the user never sees (:func:`atomic_dir`).

    Raises:
        UnwritableOutputError: the block failed because the disk (or quota) is full.
    """
    try:
        yield
    except UnwritableOutputError as exc:
        if outermost and exc.problem == DISK_FULL:
            raise UnwritableOutputError(path, DISK_FULL) from exc
        raise
    except OSError as exc:
        if is_disk_full(exc):
            raise UnwritableOutputError(path, DISK_FULL) from exc
        raise


def read_text(path: str | Path, what: str = "file") -> str:
    """The UTF-8 text of ``path``.

    Raises:
        InputError: missing (``"<what> not found"``), unreadable, or not UTF-8 text.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(path, f"{what} not found")
    try:
        return path.read_bytes().decode("utf-8")
    except UnicodeDecodeError:
        raise InputError(path, "not a UTF-8 text file (binary or corrupt)") from None
    except OSError as exc:
        raise InputError(path, f"cannot read ({exc.strerror or exc})") from None


def read_yaml_mapping(path: str | Path, what: str = "file", *,
                      empty_is_mapping: bool = False) -> dict[str, Any]:
    """The YAML mapping stored in ``path``; with ``empty_is_mapping`` an empty file reads as
    ``{}`` (run folders' own files, which may be written empty).

    Raises:
        InputError: as :func:`read_text`, or not valid YAML, or not a mapping.
    """
    import yaml

    path = Path(path)
    try:
        data = yaml.safe_load(read_text(path, what))
    except yaml.YAMLError as exc:
        raise InputError(path, f"not valid YAML ({' '.join(str(exc).split())})") from None
    if data is None and empty_is_mapping:
        data = {}
    if not isinstance(data, dict):
        raise InputError(path, "expected a YAML mapping")
    return data


def ensure_parent(path: Path) -> None:
    """Create ``path``'s parent folders; a folder that cannot be created is reported as an
    :class:`UnwritableOutputError` naming it."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except FileExistsError:
        raise UnwritableOutputError(path, "a parent of this path is a file, not a folder") \
            from None
    except OSError as exc:
        raise UnwritableOutputError(path.parent, f"cannot create the folder "
                                                 f"({exc.strerror or exc})") from None
    if not os.access(path.parent, os.W_OK | os.X_OK):
        raise UnwritableOutputError(path.parent, "folder is not writable")


def _remove(path: Path) -> None:
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path, ignore_errors=True)
    else:
        with contextlib.suppress(FileNotFoundError):
            path.unlink()


def _check_replaceable(tmp: Path, final: Path) -> None:
    """Refuse renames that would destroy something of another kind or a non-empty folder."""
    if not final.exists() or final.is_symlink():
        return
    if final.is_dir():
        if not tmp.is_dir():
            raise OutputError(final, "is a folder; refusing to replace it with a file")
        if any(final.iterdir()):
            raise OutputError(final, "is a non-empty folder; refusing to replace it")
    elif tmp.is_dir():
        raise OutputError(final, "is a file; refusing to replace it with a folder")


@contextlib.contextmanager
def atomic_path(final: str | Path) -> Iterator[Path]:
    """Yield a temporary path next to ``final``; rename it over ``final`` on success.

    The temporary name, ``.<name>.<random>.part<suffix>``, keeps ``final``'s suffix (writers
    that pick the format from the extension still work). On an exception the temporary path is
    removed and ``final`` is left untouched. An existing file is replaced; a directory never is
    (except an empty one by a directory), and a file never replaces a directory or vice versa.

    Raises:
        OutputError: ``final`` is a directory (or a file where a directory was written).
        UnwritableOutputError: the parent folder cannot be created or written.
    """
    final = Path(final)
    if final.name in ("", ".", ".."):
        raise OutputError(final, "not a file name")
    if final.is_dir() and not final.is_symlink() and any(final.iterdir()):
        # checked before writing anything: a whole render is not wasted on a doomed rename
        raise OutputError(final, "is a folder that is not empty; refusing to replace it")
    ensure_parent(final)
    tmp = final.parent / f".{final.name}.{uuid.uuid4().hex[:12]}.part{final.suffix}"
    try:
        with naming_full_disk(final):
            yield tmp
            _check_replaceable(tmp, final)
            os.replace(tmp, final)
    finally:
        if tmp.exists() or tmp.is_symlink():
            _remove(tmp)


_ATOMIC_TEMP_NAME = re.compile(r"\..+\.[0-9a-f]{12}\.part(\.[^.]+)?")


def is_atomic_temp(name: str) -> bool:
    """Whether ``name`` is the temporary name :func:`atomic_path` gives a file while writing it
    (left behind only when its process was killed between writing and renaming)."""
    return _ATOMIC_TEMP_NAME.fullmatch(name) is not None


def write_text_atomic(path: str | Path, text: str, *, in_place_when_full: bool = False) -> None:
    """Write ``text`` (UTF-8) to ``path`` atomically (temp file + rename).

    Args:
        in_place_when_full: when the disk is full, overwrite the existing file in place
            instead, within the blocks it already has (a small record that must be updated:
            a run's status says why it stopped, also when the disk is full). A reader may see
            a torn file during that one write.

    Raises:
        UnwritableOutputError: as :func:`atomic_path` (a full disk also when the text does
            not fit in the existing file's blocks).
    """
    try:
        with atomic_path(path) as tmp:
            tmp.write_text(text, encoding="utf-8")
    except UnwritableOutputError as exc:
        if not (in_place_when_full and exc.problem == DISK_FULL and Path(path).is_file()):
            raise
        data = text.encode("utf-8")
        fd = os.open(path, os.O_WRONLY)
        try:
            os.pwrite(fd, data, 0)
            os.ftruncate(fd, len(data))
        except OSError:
            raise exc from None
        finally:
            os.close(fd)


def write_bytes_atomic(path: str | Path, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically (temp file + rename)."""
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)


class HDF5Output:
    """An HDF5 file written through a Python file object whose write errors HDF5 never sees.

    HDF5 cannot close a file after a failed write (a full disk): the object it keeps
    segfaults the interpreter when it is freed later (h5py issues 914 and 2160). Here the
    first failed write is recorded, and from then on writes go to memory, read back from there,
    so HDF5 sees a consistent file and closes it cleanly; :meth:`check` and :meth:`close` then
    raise the recorded error. Only HDF5's closing metadata reaches memory: writers call
    :meth:`check` between batches. The file is garbage after a failure; callers write it
    inside a staging folder or under a temporary name.

    Attributes:
        path: the file written.
        file: the ``h5py.File`` to fill.
    """

    def __init__(self, path: str | Path) -> None:
        import h5py

        self.path = Path(path)
        self._error: OSError | None = None
        self._raw = open(self.path, "w+b")  # closed by close() or abort()
        self._pos = 0
        self._size = 0
        self._overlay: list[tuple[int, bytes]] = []  # writes after the failure, in order
        self.file = h5py.File(self, "w")

    # the file-object protocol of h5py's "fileobj" driver
    def seek(self, offset: int, whence: int = 0) -> int:
        base = {os.SEEK_SET: 0, os.SEEK_CUR: self._pos, os.SEEK_END: self._size}[whence]
        self._pos = base + offset
        return self._pos

    def tell(self) -> int:
        return self._pos

    def readinto(self, buffer: Any) -> int:
        view = memoryview(buffer).cast("B")
        n = max(0, min(len(view), self._size - self._pos))
        self._raw.seek(self._pos)
        got = self._raw.readinto(view[:n]) or 0
        view[got:n] = bytes(n - got)  # a region the failed write did not reach
        for offset, data in self._overlay:
            lo, hi = max(offset, self._pos), min(offset + len(data), self._pos + n)
            if lo < hi:
                view[lo - self._pos:hi - self._pos] = data[lo - offset:hi - offset]
        self._pos += n
        return n

    def read(self, size: int = -1) -> bytes:
        buffer = bytearray(max(0, self._size - self._pos) if size < 0 else size)
        return bytes(buffer[:self.readinto(buffer)])

    def write(self, data: Any) -> int:
        data = bytes(data)
        if self._error is None:
            try:
                self._raw.seek(self._pos)
                self._raw.write(data)
                self._raw.flush()  # a full disk shows here, not at a later flush
            except OSError as exc:
                self._error = exc
        if self._error is not None:
            self._overlay.append((self._pos, data))
        self._pos += len(data)
        self._size = max(self._size, self._pos)
        return len(data)

    def truncate(self, size: int | None = None) -> int:
        size = self._pos if size is None else size
        if self._error is None:
            try:
                self._raw.truncate(size)
            except OSError as exc:
                self._error = exc
        self._size = size
        return size

    def flush(self) -> None:
        pass  # every write is flushed as it is made

    def check(self) -> None:
        """Raise the first write error so far (call between batches, so that no more work is
        spent on a file that is lost).

        Raises:
            UnwritableOutputError: the disk is full.
            OSError: another write error, naming the file.
        """
        exc = self._error
        if exc is None:
            return
        if is_disk_full(exc):
            raise UnwritableOutputError(self.path, DISK_FULL) from exc
        raise OSError(exc.errno, exc.strerror or str(exc), str(self.path)) from exc

    def close(self) -> None:
        """Close the HDF5 file and the file under it; raise a write error that happened
        (see :meth:`check`)."""
        try:
            self.file.close()
        finally:
            try:
                self._raw.close()
            except OSError as exc:
                self._error = self._error or exc
            self._overlay.clear()
        self.check()

    def abort(self) -> None:
        """Close without reporting write errors (the file is being discarded)."""
        with contextlib.suppress(Exception):
            self.file.close()
        with contextlib.suppress(OSError):
            self._raw.close()
        self._overlay.clear()


# ------------------------------------------------------------------------------ locks
class FileLock:
    """An exclusive, non-blocking ``flock`` on ``path`` (created if missing).

    The lock belongs to this object's open file; it is released by :meth:`release`, when the
    object is garbage-collected, or by the kernel when the process ends in any way. The file
    itself is never deleted (deleting a lock file races with processes that opened it).
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self._fd: int | None = None

    @property
    def held(self) -> bool:
        return self._fd is not None

    def acquire(self, note: str = "") -> bool:
        """Try to take the lock; returns False when another open file holds it.

        ``note`` (e.g. ``"pid 12 on host"``) is written into the lock file for humans.
        """
        if self._fd is not None:
            return True
        fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            return False
        except BaseException:
            os.close(fd)
            raise
        if note:
            try:
                os.ftruncate(fd, 0)
                os.pwrite(fd, (note + "\n").encode(), 0)
            except OSError as exc:
                if not is_disk_full(exc):  # the note is for people; the lock holds without it
                    os.close(fd)
                    raise
        self._fd = fd
        return True

    def release(self) -> None:
        if self._fd is not None:
            fd, self._fd = self._fd, None
            with contextlib.suppress(OSError):
                fcntl.flock(fd, fcntl.LOCK_UN)
            os.close(fd)

    def __del__(self) -> None:
        self.release()


def lock_is_held(path: str | Path) -> bool | None:
    """Whether some open file holds the ``flock`` of ``path``; ``None`` if the file is missing.

    Probes with a shared lock, so two probes never disturb each other.
    """
    try:
        fd = os.open(path, os.O_RDONLY)
    except FileNotFoundError:
        return None
    try:
        fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
    except BlockingIOError:
        return True
    else:
        fcntl.flock(fd, fcntl.LOCK_UN)
        return False
    finally:
        os.close(fd)


def owner_note() -> str:
    """``"pid <pid> on <host>"`` of this process (stored in lock files and run status)."""
    return f"pid {os.getpid()} on {socket.gethostname()}"


# ------------------------------------------------------------------------------ folders
def _staging_prefix(name: str) -> str:
    return f".{name}."


def clean_stale_staging(final: str | Path) -> list[Path]:
    """Remove staging folders of ``final`` abandoned by killed processes; returns them.

    A staging folder is abandoned when its owner lock is free, or, without an owner file (a
    process killed between creating the folder and its lock), when it is older than a minute.
    """
    final = Path(final)
    removed: list[Path] = []
    if not final.parent.is_dir():
        return removed
    for candidate in final.parent.glob(f"{_staging_prefix(final.name)}*.tmp"):
        if not candidate.is_dir() or candidate.is_symlink():
            continue
        held = lock_is_held(candidate / _OWNER_FILE)
        if held is None:
            try:
                age = time.time() - candidate.stat().st_mtime
            except FileNotFoundError:
                continue
            if age < _STAGING_GRACE_S:
                continue
        elif held:
            continue
        shutil.rmtree(candidate, ignore_errors=True)
        removed.append(candidate)
    return removed


@contextlib.contextmanager
def atomic_dir(final: str | Path, *, replace: bool = False) -> Iterator[Path]:
    """Yield a temporary folder path to fill; rename it to ``final`` on success.

    The folder is built inside a hidden staging folder ``.<name>.<random>.tmp`` next to
    ``final`` that holds an owner lock; on an exception (including Ctrl-C / SIGTERM, see
    :class:`egs_bench.errors.Interrupted`) the staging folder is removed. Staging folders of
    the same target left by killed processes are removed first.

    Args:
        final: the folder to create.
        replace: replace an existing folder at ``final`` (the caller has checked that it may,
            see :func:`egs_bench.outputs.prepare_output`). The old folder is moved into the
            staging folder once the new one is complete, and deleted after the swap; an empty
            existing folder is replaced without ``replace``.

    Raises:
        OutputError: ``final`` exists and may not be replaced.
        UnwritableOutputError: the parent folder cannot be written.
    """
    final = Path(final)
    if final.name in ("", ".", ".."):
        raise OutputError(final, "not a folder name")
    ensure_parent(final)
    clean_stale_staging(final)
    try:
        staging = Path(tempfile.mkdtemp(prefix=_staging_prefix(final.name), suffix=".tmp",
                                        dir=final.parent))
    except OSError as exc:
        problem = DISK_FULL if is_disk_full(exc) else f"cannot write here ({exc.strerror or exc})"
        raise UnwritableOutputError(final.parent, problem) from None
    owner = FileLock(staging / _OWNER_FILE)
    try:
        with naming_full_disk(final, outermost=True):
            owner.acquire(owner_note())
            target = staging / final.name
            yield target
        if not target.is_dir():
            raise RuntimeError(f"atomic_dir: nothing was written to {target}")
        raise_if_interrupted()  # a signal whose exception was swallowed: do not publish
        old = staging / ".replaced"
        if final.exists() or final.is_symlink():
            if final.is_symlink() or not final.is_dir():
                raise OutputError(final, "is a file; refusing to replace it with a folder")
            if any(final.iterdir()) and not replace:
                raise OutputError(final, "already exists (not replaced)")
            os.rename(final, old)
        try:
            os.rename(target, final)
        except BaseException:
            if old.exists():
                os.rename(old, final)
            raise
    finally:
        owner.release()
        shutil.rmtree(staging, ignore_errors=True)


def to_plain(value: Any) -> Any:
    """Convert numpy scalars/arrays and paths inside ``value`` to plain YAML/JSON types."""
    if isinstance(value, Mapping):
        return {str(k): to_plain(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [to_plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return to_plain(value.tolist())
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, Path):
        return str(value)
    return value
