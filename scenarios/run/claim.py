"""One process per output directory: a run, study or assessment claims its ``--out`` before any work.

A claim is an exclusive, non-blocking ``flock(2)`` on the directory itself, held by the process until it ends. The
kernel drops the lock whenever the holder ends — normally, by a signal, by SIGKILL or the out-of-memory killer — so a
claim is never stale: there is no lock file to clean up and nothing a killed run could leave behind to block the next
one. Two processes started together into one ``--out`` therefore cannot both write there: the second is refused with
one line (exit 2) before it reads, clears or writes anything, naming the holder's PID where Linux's ``/proc/locks``
tells it.

A file system that cannot lock a directory (NFS locks only files open for writing) is locked through a file
``.offtrack.lock`` in the directory instead, the same way (it holds the last holder's PID, for the message only; it is
never the lock's state). One that cannot lock at all is used unclaimed, with a note on stderr saying so.

A process claims a directory once; claiming it again (a test's repeated ``new_run_dir``) is a no-op.
"""

from __future__ import annotations

import errno
import fcntl
import os
import sys
from pathlib import Path

from vehicle_model.errors import InputError

LOCK_FILE = ".offtrack.lock"
"""The lock file of a directory whose file system cannot lock the directory itself."""

_UNSUPPORTED = {errno.EBADF, errno.ENOLCK, errno.EOPNOTSUPP, errno.ENOSYS, errno.EINVAL}
"""What ``flock`` raises where the file system cannot lock (a directory on NFS, Lustre without ``-o flock``)."""

_claimed: dict[str, int] = {}
"""The directories this process holds (real path → the descriptor holding the lock, open until the process ends)."""


def claim_directory(directory: Path, option: str = "--out") -> None:
    """Claim ``directory`` (it exists) for this process until the process ends.

    Parameters
    ----------
    directory
        The output directory.
    option
        The command-line option that named it, for the message.

    Raises
    ------
    InputError
        Another live process holds it: one line naming ``option``, the directory and, where known, the PID.
    """
    key = os.path.realpath(directory)
    if key in _claimed:
        return
    try:
        fd = os.open(key, os.O_RDONLY | os.O_DIRECTORY)
    except OSError as exc:
        raise InputError(f"{option} {key} cannot be opened: {exc.strerror or exc}") from None
    try:
        _lock(fd, key, option)
    except OSError as exc:
        os.close(fd)
        if exc.errno not in _UNSUPPORTED:
            raise
        fd = _claim_by_file(key, option)
        if fd is None:
            return
    except BaseException:
        os.close(fd)
        raise
    _claimed[key] = fd


def _claim_by_file(key: str, option: str) -> int | None:
    """Claim ``key`` through its :data:`LOCK_FILE`; None where the file system cannot lock at all."""
    path = os.path.join(key, LOCK_FILE)
    try:
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o666)
    except OSError as exc:
        raise InputError(f"{option} {key}: its lock file {path} cannot be made: {exc.strerror or exc}") from None
    try:
        _lock(fd, path, option, directory=key)
    except OSError as exc:
        os.close(fd)
        if exc.errno not in _UNSUPPORTED:
            raise
        print(
            f"note: {option} {key}: this file system cannot lock, so another process writing into it is not kept out",
            file=sys.stderr,
        )
        return None
    except BaseException:
        os.close(fd)
        raise
    os.ftruncate(fd, 0)
    os.write(fd, f"{os.getpid()}\n".encode())
    return fd


def _lock(fd: int, path: str, option: str, directory: str | None = None) -> None:
    """Lock ``fd`` (of ``path``) exclusively without waiting; a holder → :class:`InputError`."""
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        holder = lock_holder(fd)
        by = f"process {holder}" if holder is not None else "another process"
        raise InputError(
            f"{option} {directory or path} is in use by {by} (an offtrack run, study or assessment writing there); "
            f"wait for it to end or choose another {option}"
        ) from None


def lock_holder(fd: int) -> int | None:
    """The PID holding a ``flock`` on the file of ``fd``, read from Linux's ``/proc/locks``; None where unknown."""
    stat = os.fstat(fd)
    inode = f"{os.major(stat.st_dev):02x}:{os.minor(stat.st_dev):02x}:{stat.st_ino}"
    try:
        with open("/proc/locks") as fh:
            lines = fh.read().splitlines()
    except OSError:
        return None
    for line in lines:
        fields = line.split()
        if "->" in fields or len(fields) < 6:  # a waiter, or a line this reader does not know
            continue
        if fields[1] == "FLOCK" and fields[5] == inode:
            return int(fields[4])
    return None
