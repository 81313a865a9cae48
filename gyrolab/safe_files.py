"""Creating files where another user or process may also write: nothing followed, nothing mixed.

Every file gyrolab writes (the runner's lock, journal and results, combined files, figures, docs
tables) is made through this module:

- a new file is written inside a private directory (``tempfile.mkdtemp``: mode 0700, a fresh
  random name) next to its destination, so no one else can put a link or a FIFO where it is being
  written, then renamed over its destination (``atomic_replace``);
- the destination itself is checked just before the rename (``check_replaceable``): nothing there,
  or a regular file we own; a symbolic link, a directory, a FIFO or device, or another user's file
  is refused with one line (``UnsafePathError``; commands exit 2);
- a file opened in place (the lock) is opened with ``O_NOFOLLOW | O_NONBLOCK`` and checked, by its
  open descriptor, to be a regular file we own (``open_regular``).

Names taken from a file's content (a scene label, a member name) go into file names only through
``safe_name`` (a basename of ``[A-Za-z0-9._+=-]``), and the resulting path is checked to lie under
the directory the user named (``inside``).

Background: the open(2) flags O_NOFOLLOW / O_EXCL and the rename(2) semantics (the destination's
link itself is replaced, not its target) as in the Linux man pages; the private-directory pattern
is that of Python's ``tempfile`` module.
"""

import errno
import fcntl
import os
import re
import shutil
import socket
import stat
import tempfile
import time
from contextlib import contextmanager
from pathlib import Path


class UnsafePathError(ValueError):
    """A path gyrolab will not write through; the message is one line naming it and why."""


def _kind(mode):
    if stat.S_ISLNK(mode):
        return "a symbolic link"
    if stat.S_ISDIR(mode):
        return "a directory"
    if stat.S_ISFIFO(mode):
        return "a FIFO"
    if stat.S_ISSOCK(mode):
        return "a socket"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "a device"
    return "not a regular file"


def _problem(st):
    """Why a file with lstat/fstat result ``st`` must not be written or replaced, or None."""
    if not stat.S_ISREG(st.st_mode):
        return f"is {_kind(st.st_mode)}"
    if st.st_uid != os.geteuid():
        return f"belongs to another user (uid {st.st_uid})"
    return None


def check_replaceable(path):
    """UnsafePathError unless ``path`` is absent or a regular file owned by us (never follows a link)."""
    try:
        st = os.lstat(path)
    except FileNotFoundError:
        return
    problem = _problem(st)
    if problem:
        raise UnsafePathError(f"{path}: {problem}; gyrolab writes only new files or its own regular files there")


def open_regular(path, flags, mode=0o644):
    """``os.open(path, flags | O_NOFOLLOW | O_NONBLOCK | O_CLOEXEC)`` checked, by the descriptor, to
    be a regular file we own; UnsafePathError (descriptor closed) otherwise.  O_NONBLOCK: a FIFO
    there cannot hang the open (it is refused after it)."""
    try:
        fd = os.open(path, flags | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC, mode)
    except OSError as err:
        if err.errno in (errno.ELOOP, errno.EISDIR, errno.ENOTDIR, errno.ENXIO):  # a link, a directory, ...
            try:
                what = _problem(os.lstat(path)) or err.strerror
            except OSError:
                what = err.strerror
            raise UnsafePathError(f"{path}: {what}; gyrolab does not open it") from None
        raise
    problem = _problem(os.fstat(fd))
    if problem:
        os.close(fd)
        raise UnsafePathError(f"{path}: {problem}; gyrolab does not open it")
    return fd


def check_output(path):
    """UnsafePathError unless ``path`` can be written by :func:`atomic_replace`: its directory
    exists and ``path`` is absent or a regular file of ours.  Call it before the work."""
    parent = Path(path).parent
    if not parent.is_dir():
        raise UnsafePathError(f"{path}: no such directory {parent}")
    check_replaceable(path)


def fsync_dir(directory):
    fd = os.open(directory, os.O_RDONLY | os.O_DIRECTORY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def temporary_prefix(path):
    """The prefix of the private directories ``atomic_replace`` writes ``path`` in: hidden, this
    process's pid (``.<name>.tmp<pid>.``; a random part follows)."""
    path = Path(path)
    return f".{path.name}.tmp{os.getpid()}."


@contextmanager
def private_dir(path):
    """A new directory (mode 0700) next to ``path``, removed with everything in it afterwards."""
    path = Path(path)
    where = Path(tempfile.mkdtemp(prefix=temporary_prefix(path), dir=path.parent))
    try:
        yield where
    finally:
        shutil.rmtree(where, ignore_errors=True)


def atomic_replace(path, write_to, before_replace=None):
    """Call ``write_to(tmp)`` with a path in a private directory next to ``path``, fsync that file
    and rename it to ``path``: ``path`` is old or whole, and nothing else is ever written.
    ``path`` must be absent or a regular file of ours (checked before the work and again before
    the rename: UnsafePathError).  ``before_replace()``, if given, runs just before the rename and
    may raise to cancel it."""
    path = Path(path)
    check_replaceable(path)
    with private_dir(path) as where:
        tmp = where / path.name
        write_to(tmp)
        fd = open_regular(tmp, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
        if before_replace is not None:
            before_replace()
        check_replaceable(path)
        os.replace(tmp, path)  # rename(2) replaces a link at ``path`` itself, never its target
    fsync_dir(path.parent)


def atomic_write(path, write, mode=0o644):
    """Call ``write(fileobj)`` on a new binary file (permissions ``mode``), then as :func:`atomic_replace`."""

    def write_to(tmp):
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW | os.O_CLOEXEC, mode)
        with os.fdopen(fd, "wb") as fh:
            write(fh)

    atomic_replace(path, write_to)


def write_text(path, text):
    """``path`` holds ``text`` (UTF-8) afterwards, written as :func:`atomic_write`."""
    data = str(text).encode()
    atomic_write(path, lambda fh: fh.write(data))


def remove_entry(path):
    """Remove the file, link or directory tree at ``path`` without following a link."""
    path = Path(path)
    try:
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path, ignore_errors=True)
        else:
            path.unlink()
    except FileNotFoundError:
        pass


_UNSAFE_CHARS = re.compile(r"[^A-Za-z0-9._+=-]+")
MAX_NAME = 80


def safe_name(label, fallback):
    """``label`` (text from a file: a scene, a member) as a file-name part: runs of characters other
    than ``[A-Za-z0-9._+=-]`` become ``_``, leading dots and dashes are dropped, at most MAX_NAME
    characters; ``fallback`` when nothing is left (``..``, ``/``, "")."""
    text = _UNSAFE_CHARS.sub("_", str(label)).lstrip(".-_")[:MAX_NAME].rstrip("._")
    return text or str(fallback)


def inside(base, path):
    """``path`` (resolved) after checking it lies under the directory ``base`` (resolved);
    UnsafePathError otherwise."""
    base, resolved = Path(base).resolve(), Path(path).resolve()
    if resolved != base and base not in resolved.parents:
        raise UnsafePathError(f"{path}: outside {base}; a name from the file may not choose where to write")
    return resolved


# --------------------------------------------------------------------------- one writer per output


class OutputBusyError(ValueError):
    """Another process is writing the output right now; the message is one line naming it."""


def lock_path(out):
    return Path(f"{out}.lock")


def temporary_name(path):
    """The start of the names of the private directories ``atomic_replace`` writes ``path`` in
    (hidden, with this process's pid; gyrolab/safe_files.py adds a random part)."""
    path = Path(path)
    return path.with_name(temporary_prefix(path))


def remove_stale_temporaries(path):
    """Remove the ``.<name>.tmp<pid>`` files and ``.<name>.tmp<pid>.<random>`` private directories
    next to ``path`` that a killed assembly or combine left (links removed, never followed); returns
    the removed paths.  Call with the output's lock held: every writer of ``path`` holds it, so
    none is in use."""
    path = Path(path)
    removed = []
    if not path.parent.is_dir():
        return removed
    for tmp in path.parent.glob(f".{path.name}.tmp*"):
        pid, dot, _ = tmp.name[len(f".{path.name}.tmp") :].partition(".")
        if pid.isdigit() and (not dot or (tmp.is_dir() and not tmp.is_symlink())):
            remove_entry(tmp)
            removed.append(tmp)
    return removed


def lock_identity():
    """What the lock file holds: ``<pid> <host> <start time, UTC>`` of the writer."""
    started = time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())
    return f"{os.getpid()} {socket.gethostname()} {started}\n"


class OutputLock:
    """Exclusive, non-blocking lock on ``<out>.lock``; OutputBusyError naming the holder if taken.

    The lock file (``lock_identity``: pid, host, start time) is opened with O_NOFOLLOW and must be a
    regular file of ours (else UnsafePathError: a link or a FIFO planted there is never followed);
    a lock left by a killed writer holds no flock and is simply taken over.  The file is removed
    on release; the inode check after locking makes that safe against a writer that opened the
    file just before the removal.
    """

    def __init__(self, out):
        self.out = Path(out)
        self.path = lock_path(out)
        self.fd = None

    def check_free(self):
        """OutputBusyError if another process holds the lock; creates nothing."""
        try:
            fd = open_regular(self.path, os.O_RDONLY)
        except FileNotFoundError:
            return
        try:
            fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
        except BlockingIOError:
            self._refuse(fd)
        os.close(fd)

    def _refuse(self, fd):
        words = os.read(fd, 200).decode(errors="replace").split()
        os.close(fd)
        holder = words[0] if words and words[0].isdigit() else "?"
        where = f" (host {words[1]}, since {words[2]})" if len(words) >= 3 else ""
        raise OutputBusyError(
            f"output.path={self.out}: another gyrolab (pid {holder}) is writing it right now{where}; "
            "wait for it to finish or choose another output.path"
        )

    def acquire(self):
        while True:
            fd = open_regular(self.path, os.O_RDWR | os.O_CREAT)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                self._refuse(fd)
            try:
                same = os.lstat(self.path).st_ino == os.fstat(fd).st_ino
            except FileNotFoundError:
                same = False
            if same:
                break
            os.close(fd)  # the previous holder removed the file under us: lock the new one
        os.ftruncate(fd, 0)
        os.write(fd, lock_identity().encode())
        self.fd = fd
        return self

    def release(self):
        if self.fd is not None:
            try:
                if os.lstat(self.path).st_ino == os.fstat(self.fd).st_ino:
                    self.path.unlink()
            except FileNotFoundError:
                pass
            os.close(self.fd)
            self.fd = None

    def __enter__(self):
        return self.acquire()

    def __exit__(self, *exc):
        self.release()
