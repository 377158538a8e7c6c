"""Writing the project's files so that a kill, a full disk or a second run
never leaves one torn, mixed or lost (docs/reliability.md lists every writer).

- `replace(path)`: a file object on a new temporary file beside path (same
  directory, a unique name); leaving the block flushes it, fsyncs it and
  renames it over path (os.replace), so that a reader, or the next run after
  a kill, finds the old file or the new one, never a mix. `write_text`,
  `write_bytes`, `write_json` and `save_figure` are that for a whole text, a
  JSON value and a matplotlib figure; torch.save, numpy and csv write into
  `replace(path, "wb")`'s file.
- `RowAppender`: a JSON-lines file of results appended one whole line at a
  time, each fsynced as it comes (a killed job resumes from them): a line
  cut by a kill is removed when the file is opened again, and a write that
  fails is cut back off, so that every line stays a whole row.
- `exclusive(lock_file)`: an exclusive lock (filelock's flock) held for a
  whole update; its holder's pid and host in a file beside it, named when
  another run is refused. The kernel drops the lock of a process that dies
  (filelock closes it in forked children too), so a lock left by a dead
  process is taken over at once; its stale holder file is replaced.

Errors: an OSError while writing (ENOSPC, EFBIG, EIO, …) becomes WriteError,
one line naming the file and the error; the old file is left whole and the
temporary file removed. A file whose name is taken by a device (/dev/null)
or a FIFO is written to directly: there is nothing to replace.
"""

import contextlib
import errno
import json
import os
import socket
import tempfile
import time
from pathlib import Path

import filelock

from regrasp_drake.errors import InputError

# Files are created with the permissions open() would give them (the umask),
# not tempfile's 0600.
_UMASK = os.umask(0)
os.umask(_UMASK)
_HOST = socket.gethostname()
# A temporary file's name: .<target>.<host>.<pid>.<random>.tmp, so that the
# next write of the target removes those its dead writers left (a SIGKILL
# runs no clean-up).
_TMP_SUFFIX = ".tmp"
# How long a run that would be refused a lock tries again first, [s].
GRACE_S = 1.0


class WriteError(InputError):
    """A file could not be written (disk full, a write error); its previous
    content is kept. One line, as InputError: the command line prints it
    and exits 2."""


class LockedError(InputError):
    """Another run holds the lock of a file or directory this one would
    update; the message names it (pid, host)."""


def _write_error(path, e: OSError) -> WriteError:
    name = errno.errorcode.get(e.errno, "") if e.errno else ""
    return WriteError(f"{path}: not written ({e.strerror or e}"
                      f"{', ' + name if name else ''}); what was there before "
                      "is kept")


def _target(path) -> Path:
    """The file a write to path replaces: a link's target, not the link."""
    path = Path(path)
    return Path(os.path.realpath(path)) if path.is_symlink() else path


def pid_alive(pid: int) -> bool:
    """Whether process pid runs on this host."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _remove_stale_temporaries(path: Path) -> None:
    """Removes the temporary files of path left by writers of this host that
    are no longer running."""
    prefix = f".{path.name}."
    for tmp in path.parent.glob(f"{glob_escape(prefix)}*{_TMP_SUFFIX}"):
        parts = tmp.name[len(prefix):-len(_TMP_SUFFIX)].split(".")
        if (len(parts) >= 3 and ".".join(parts[:-2]) == _HOST
                and parts[-2].isdigit() and not pid_alive(int(parts[-2]))):
            tmp.unlink(missing_ok=True)


def glob_escape(text: str) -> str:
    """text matched literally by Path.glob."""
    return "".join(f"[{c}]" if c in "*?[" else c for c in text)


@contextlib.contextmanager
def replace(path, mode: str = "w", **open_args):
    """Yields a file opened with `mode` ("w" or "wb") on a temporary file
    beside path; on a clean exit it is fsynced and renamed over path (the
    new file has the old one's permissions, or the umask's). On an error
    the temporary file is removed and path left as it was; an OSError is
    raised as WriteError naming path."""
    if mode not in ("w", "wb"):
        raise ValueError(f"mode: got {mode!r}, expected 'w' or 'wb'")
    path = _target(path)
    if path.exists() and not path.is_file():  # /dev/null, a FIFO
        try:
            with open(path, mode, **open_args) as f:
                yield f
        except OSError as e:
            raise _write_error(path, e) from None
        return
    tmp = None
    try:
        _remove_stale_temporaries(path)
        f = tempfile.NamedTemporaryFile(
            mode, dir=path.parent, delete=False, suffix=_TMP_SUFFIX,
            prefix=f".{path.name}.{_HOST}.{os.getpid()}.", **open_args)
        tmp = Path(f.name)
        with f:
            yield f
            f.flush()
            os.fsync(f.fileno())
            os.fchmod(f.fileno(), path.stat().st_mode & 0o7777
                      if path.exists() else 0o666 & ~_UMASK)
        os.replace(tmp, path)
        tmp = None
        _fsync_directory(path.parent)
    except OSError as e:
        raise _write_error(path, e) from None
    finally:
        if tmp is not None:
            tmp.unlink(missing_ok=True)


def _fsync_directory(directory: Path) -> None:
    """Makes a rename in directory durable."""
    fd = os.open(directory, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def write_text(path, text: str) -> Path:
    """Writes text to path atomically (replace). Returns path."""
    with replace(path, "w", encoding="utf-8") as f:
        f.write(text)
    return Path(path)


def write_bytes(path, data: bytes) -> Path:
    """Writes data to path atomically (replace). Returns path."""
    with replace(path, "wb") as f:
        f.write(data)
    return Path(path)


def write_json(path, data, indent: int | None = 1) -> Path:
    """Writes data as JSON (and a newline) to path atomically. Returns path."""
    return write_text(path, json.dumps(data, indent=indent) + "\n")


def save_figure(fig, path, **savefig_args) -> Path:
    """fig.savefig to path atomically, in the format of path's extension."""
    path = Path(path)
    with replace(path, "wb") as f:
        fig.savefig(f, format=path.suffix.lstrip(".").lower(), **savefig_args)
    return path


class RowAppender:
    """A JSON-lines file opened to append whole lines (`append`), each
    written, flushed and fsynced as it comes: a killed job keeps every row
    written so far. Opening it removes a last line cut by a kill (no newline
    at its end; its work runs again); a write that fails (disk full) is cut
    back off and raised as WriteError, so that every line stays whole."""

    def __init__(self, path):
        self.path = Path(path)
        try:
            self._fd = os.open(self.path, os.O_RDWR | os.O_CREAT | os.O_APPEND,
                               0o666)
            data_end = os.lseek(self._fd, 0, os.SEEK_END)
            if data_end:
                whole = _whole_lines_end(self._fd, data_end)
                if whole != data_end:
                    os.ftruncate(self._fd, whole)
        except OSError as e:
            raise _write_error(self.path, e) from None

    def append(self, line: str) -> None:
        """Appends line (one JSON row, no newline) and a newline."""
        data = (line + "\n").encode()
        end = os.lseek(self._fd, 0, os.SEEK_END)
        try:
            view = memoryview(data)
            while view:
                view = view[os.write(self._fd, view):]
            os.fsync(self._fd)
        except OSError as e:
            with contextlib.suppress(OSError):
                os.ftruncate(self._fd, end)
            raise _write_error(self.path, e) from None

    def close(self) -> None:
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def _whole_lines_end(fd: int, size: int) -> int:
    """The end of the last whole line (after its newline) of a file of
    `size` bytes: 0 when it has none."""
    block = 1 << 16
    end = size
    while end > 0:
        start = max(0, end - block)
        chunk = os.pread(fd, end - start, start)
        k = chunk.rfind(b"\n")
        if k >= 0:
            return start + k + 1
        end = start
    return 0


def holder_path(lock_file) -> Path:
    """The file beside a lock that names its holder (pid, host, since)."""
    lock_file = Path(lock_file)
    return lock_file.with_name(lock_file.name + ".holder")


def _read_holder(lock_file) -> dict:
    try:
        holder = json.loads(holder_path(lock_file).read_text())
        return holder if isinstance(holder, dict) else {}
    except (OSError, ValueError):
        return {}


def _describe(holder: dict) -> str:
    if not holder:
        return "another run (its holder not yet recorded)"
    return (f"pid {holder.get('pid')} on host {holder.get('host')}, since "
            f"{holder.get('since')}")


@contextlib.contextmanager
def exclusive(lock_file, *, what: str, wait: bool):
    """Holds the exclusive lock lock_file for the block, its holder (pid,
    host, since) written in holder_path(lock_file) and removed at the end.
    wait: wait for a holder to finish (a short update: the library's);
    else refuse at once with LockedError naming `what` and the holder (a
    long run: a data set, a map). A lock whose holder died is the
    kernel's to drop, so it is taken at once; its holder file is replaced."""
    lock_file = Path(lock_file)
    lock = filelock.FileLock(lock_file)
    try:
        try:
            lock.acquire(timeout=-1 if wait else 0)
        except filelock.Timeout:
            # A holder that just died may have left a freshly forked child
            # that has not yet closed its copy of the lock (filelock closes
            # it there); a new holder may not have written its file yet.
            lock.acquire(timeout=GRACE_S)
    except filelock.Timeout:
        raise LockedError(
            f"{what}: in use by {_describe(_read_holder(lock_file))} "
            f"({lock_file}), expected one run at a time on it: wait for that "
            "run to end, or give another path") from None
    except OSError as e:
        raise _write_error(lock_file, e) from None
    try:
        write_json(holder_path(lock_file), {
            "pid": os.getpid(), "host": _HOST,
            "since": time.strftime("%Y-%m-%d %H:%M:%S %Z")}, indent=None)
        yield
    finally:
        holder_path(lock_file).unlink(missing_ok=True)
        lock.release()
