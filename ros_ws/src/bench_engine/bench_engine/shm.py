"""Fast DDS's shared-memory files of this process, released without its DDS teardown (bench_engine.launcher:
a single-process run's participant is never destroyed).

A Fast DDS participant on this host keeps files in /dev/shm: its segment ``fastrtps_<16 hex>`` and the ports it
listens on, ``fastrtps_port<N>`` (with the named semaphore ``sem.fastrtps_port<N>_mutex``), each with a lock file
(``_el``, or ``_sl`` for a port several listeners share) that its owners (the segment's participant, the port's
listeners) hold an ``flock`` on while they live.
Destroying the participant removes the files it alone uses; a process that ends without that leaves them behind
for good (Fast DDS's ``fastdds shm clean`` removes such files later: those whose lock nobody holds).
:func:`release_own` removes them while the participant still runs: the files whose lock this process holds and
no other process does. Unlinking takes only the names: the mappings this process has stay valid until it exits,
and no other process uses them (a run's domain is its own: bench_engine.domains).
"""

from __future__ import annotations

import os
from pathlib import Path

SHM = Path("/dev/shm")
PREFIX = "fastrtps_"
LOCK_SUFFIXES = ("_el", "_sl")


def _lock_holders(locks: Path = Path("/proc/locks")) -> dict[tuple[int, int, int], set[int]]:
    """(device major, minor, inode) -> the processes that hold a lock on that file, from /proc/locks (lines
    ``N: FLOCK ADVISORY WRITE PID MAJ:MIN:INODE START END``, the device in hex; waiters' lines, ``N: -> ...``,
    are skipped)."""
    holders: dict[tuple[int, int, int], set[int]] = {}
    for line in locks.read_text().splitlines():
        fields = line.split()
        if len(fields) < 6 or fields[1] == "->":
            continue
        try:
            major, minor, inode = fields[5].split(":")
            holders.setdefault((int(major, 16), int(minor, 16), int(inode)), set()).add(int(fields[4]))
        except ValueError:
            continue
    return holders


def own_lock_files() -> list[Path]:
    """The Fast DDS lock files this process has open (/proc/self/fd)."""
    found = set()
    for fd in Path("/proc/self/fd").iterdir():
        try:
            path = Path(os.readlink(fd))
        except OSError:  # the descriptor of the listing itself, or one closed meanwhile
            continue
        if path.parent == SHM and path.name.startswith(PREFIX) and path.name.endswith(LOCK_SUFFIXES):
            found.add(path)
    return sorted(found)


def release_own() -> list[str]:
    """Remove the Fast DDS files of this process that no other process uses (module docstring); returns their
    names. Does nothing where there is no /proc/locks or /dev/shm (not Linux)."""
    if not (SHM.is_dir() and Path("/proc/locks").is_file()):
        return []
    holders, me, removed = _lock_holders(), os.getpid(), []
    for lock in own_lock_files():
        try:
            st = lock.stat()
        except OSError:
            continue
        if holders.get((os.major(st.st_dev), os.minor(st.st_dev), st.st_ino), set()) - {me}:
            continue  # another process uses it too
        base = lock.name[: -len(LOCK_SUFFIXES[0])]
        for name in (base, lock.name, f"sem.{base}_mutex"):
            try:
                (SHM / name).unlink()
                removed.append(name)
            except FileNotFoundError:
                pass
    return removed
