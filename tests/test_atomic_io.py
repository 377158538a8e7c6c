"""The atomic writes, appended rows and locks every writer uses: a failed
write leaves the old file whole and no temporary file; a torn or failed row
is cut off; a lock is refused naming its holder and taken over from a dead
one."""

import contextlib
import json
import os
import resource
import signal
import socket
import stat
import tempfile
import time
import unittest
from pathlib import Path

from regrasp_drake import atomic_io
from regrasp_drake.atomic_io import LockedError, RowAppender, WriteError
from regrasp_drake.map_rows import read_rows


@contextlib.contextmanager
def file_size_limit(limit_bytes: int):
    """RLIMIT_FSIZE in this process for the block: a write beyond
    limit_bytes fails with EFBIG, as on a full disk (Python ignores
    SIGXFSZ)."""
    soft, hard = resource.getrlimit(resource.RLIMIT_FSIZE)
    resource.setrlimit(resource.RLIMIT_FSIZE, (limit_bytes, hard))
    try:
        yield
    finally:
        resource.setrlimit(resource.RLIMIT_FSIZE, (soft, hard))


def temporaries(directory) -> list[str]:
    """The temporary files atomic_io left in directory."""
    return sorted(p.name for p in Path(directory).glob(".*.tmp"))


class ReplaceTest(unittest.TestCase):
    def setUp(self):
        self.tmp = tempfile.TemporaryDirectory()
        self.dir = Path(self.tmp.name)

    def tearDown(self):
        self.tmp.cleanup()

    def test_new_file_has_the_umasks_mode_and_an_old_one_keeps_its(self):
        path = self.dir / "a.json"
        atomic_io.write_json(path, {"x": 1})
        umask = os.umask(0)
        os.umask(umask)
        self.assertEqual(stat.S_IMODE(path.stat().st_mode), 0o666 & ~umask)
        path.chmod(0o640)
        atomic_io.write_json(path, {"x": 2})
        self.assertEqual(json.loads(path.read_text()), {"x": 2})
        self.assertEqual(stat.S_IMODE(path.stat().st_mode), 0o640)
        self.assertEqual(temporaries(self.dir), [])

    def test_failed_write_keeps_the_old_file_and_no_temporary(self):
        path = self.dir / "a.txt"
        atomic_io.write_text(path, "old\n")
        with file_size_limit(1000), self.assertRaises(WriteError) as caught:
            atomic_io.write_text(path, "new\n" * 1000)
        self.assertEqual(path.read_text(), "old\n")
        self.assertEqual(temporaries(self.dir), [])
        message = str(caught.exception)
        self.assertIn(str(path), message)
        self.assertIn("EFBIG", message)
        self.assertNotIn("\n", message)

    def test_an_exception_in_the_writer_keeps_the_old_file(self):
        path = self.dir / "a.bin"
        atomic_io.write_bytes(path, b"old")
        with self.assertRaises(RuntimeError), atomic_io.replace(path, "wb") as f:
            f.write(b"half")
            raise RuntimeError("the writer failed")
        self.assertEqual(path.read_bytes(), b"old")
        self.assertEqual(temporaries(self.dir), [])

    def test_a_link_is_followed_and_a_device_written_in_place(self):
        target = self.dir / "target.json"
        link = self.dir / "link.json"
        link.symlink_to(target)
        atomic_io.write_json(link, [1])
        self.assertTrue(link.is_symlink())
        self.assertEqual(json.loads(target.read_text()), [1])
        atomic_io.write_json(os.devnull, [2])  # not replaced by a file
        self.assertTrue(stat.S_ISCHR(os.stat(os.devnull).st_mode))

    def test_temporaries_of_dead_writers_are_removed_not_live_ones(self):
        path = self.dir / "a.json"
        host = socket.gethostname()
        pid = os.fork()
        if pid == 0:
            os._exit(0)
        os.waitpid(pid, 0)  # a pid no process has now
        dead = self.dir / f".a.json.{host}.{pid}.x1.tmp"
        live = self.dir / f".a.json.{host}.{os.getpid()}.x2.tmp"
        elsewhere = self.dir / f".a.json.otherhost.{pid}.x3.tmp"
        for p in (dead, live, elsewhere):
            p.write_text("cut")
        atomic_io.write_json(path, {})
        self.assertEqual(temporaries(self.dir), sorted([live.name,
                                                        elsewhere.name]))


class RowAppenderTest(unittest.TestCase):
    def setUp(self):
        self.tmp = tempfile.TemporaryDirectory()
        self.path = Path(self.tmp.name) / "rows.jsonl"

    def tearDown(self):
        self.tmp.cleanup()

    def test_a_torn_last_line_is_cut_when_opened_again(self):
        self.path.write_text('{"k": 1}\n{"k": 2}\n{"k": 3, "sq')
        with RowAppender(self.path) as rows:
            self.assertEqual(self.path.read_text(), '{"k": 1}\n{"k": 2}\n')
            rows.append('{"k": 3}')
        self.assertEqual(self.path.read_text(),
                         '{"k": 1}\n{"k": 2}\n{"k": 3}\n')

    def test_a_line_with_no_newline_at_all_is_cut(self):
        self.path.write_text('{"k": 1')
        with RowAppender(self.path):
            pass
        self.assertEqual(self.path.read_bytes(), b"")

    def test_a_failed_append_is_cut_back_off(self):
        with RowAppender(self.path) as rows:
            rows.append(json.dumps({"k": 1}))
            size = self.path.stat().st_size
            # Room for part of the next row only: a short write, then EFBIG.
            with file_size_limit(size + 5), \
                    self.assertRaises(WriteError) as caught:
                rows.append(json.dumps({"k": 2, "pad": "x" * 100}))
            self.assertEqual(self.path.stat().st_size, size)
            rows.append(json.dumps({"k": 3}))
        self.assertIn(str(self.path), str(caught.exception))
        key = lambda row: row["k"]  # noqa: E731
        self.assertEqual(sorted(read_rows(self.path, key)), [1, 3])


class ExclusiveTest(unittest.TestCase):
    def setUp(self):
        self.tmp = tempfile.TemporaryDirectory()
        self.lock = Path(self.tmp.name) / "x.lock"

    def tearDown(self):
        self.tmp.cleanup()

    def _hold_in_child(self, *, orphan: bool):
        """A child process that takes the lock and reports ready; with
        orphan, it forks a grandchild first (which inherits its
        descriptors and outlives it). Returns (child pid, grandchild pid)."""
        ready_r, ready_w = os.pipe()
        pid = os.fork()
        if pid == 0:
            os.close(ready_r)
            with atomic_io.exclusive(self.lock, what="x", wait=False):
                grandchild = os.fork() if orphan else 0
                if orphan and grandchild == 0:
                    time.sleep(30)
                    os._exit(0)
                os.write(ready_w, str(grandchild).encode())
                time.sleep(30)
            os._exit(0)
        os.close(ready_w)
        grandchild = int(os.read(ready_r, 100) or 0)
        os.close(ready_r)
        return pid, grandchild

    def test_a_second_holder_is_refused_naming_the_first(self):
        pid, _ = self._hold_in_child(orphan=False)
        try:
            with self.assertRaises(LockedError) as caught, \
                    atomic_io.exclusive(self.lock, what="data set D",
                                        wait=False):
                pass
        finally:
            os.kill(pid, signal.SIGKILL)
            os.waitpid(pid, 0)
        message = str(caught.exception)
        self.assertIn("data set D: in use by pid " + str(pid), message)
        self.assertIn(f"on host {socket.gethostname()}", message)

    def test_a_dead_holders_lock_is_taken_over_at_once(self):
        """Killed while holding the lock, its forked child still running:
        the lock is free, and its holder file names the new holder."""
        pid, grandchild = self._hold_in_child(orphan=True)
        os.kill(pid, signal.SIGKILL)
        os.waitpid(pid, 0)
        holder = atomic_io.holder_path(self.lock)
        try:
            self.assertEqual(json.loads(holder.read_text())["pid"], pid)
            start = time.monotonic()
            with atomic_io.exclusive(self.lock, what="x", wait=False):
                self.assertEqual(json.loads(holder.read_text())["pid"],
                                 os.getpid())
            self.assertLess(time.monotonic() - start, atomic_io.GRACE_S + 1)
            self.assertFalse(holder.exists())
        finally:
            os.kill(grandchild, signal.SIGKILL)  # not our child: not waited


if __name__ == "__main__":
    unittest.main()
