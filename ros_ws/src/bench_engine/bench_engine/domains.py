"""ROS_DOMAIN_ID reservations: one bench run per domain on this host, so runs never hear each other.

A run holds an exclusive ``flock`` on ``$TMPDIR/tracking_bench_domains/<id>.lock`` for its lifetime (released
by the OS even if the process is killed). ``reserve(None)`` takes the first free domain; ``reserve(id)`` takes
that one or fails naming the run that holds it.
"""

from __future__ import annotations

import fcntl
import os
import tempfile
from pathlib import Path

FIRST_AUTO, LAST_DOMAIN = 1, 101
LOCK_DIR = Path(tempfile.gettempdir()) / "tracking_bench_domains"


class DomainInUse(RuntimeError):
    """The requested ROS_DOMAIN_ID is held by another bench run."""


class Reservation:
    """An exclusive hold on one ROS domain id; release() or process exit frees it."""

    def __init__(self, domain: int, handle) -> None:
        self.domain = domain
        self._handle = handle

    def release(self) -> None:
        if self._handle is not None:
            self._handle.close()
            self._handle = None


def _try(domain: int):
    LOCK_DIR.mkdir(exist_ok=True)
    handle = open(LOCK_DIR / f"{domain}.lock", "a+")
    try:
        fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        handle.seek(0)
        holder = handle.read().strip()
        handle.close()
        return None, holder
    handle.seek(0)
    handle.truncate()
    handle.write(f"pid {os.getpid()}\n")
    handle.flush()
    return handle, ""


def reserve(domain: int | None) -> Reservation:
    """Reserve ``domain`` (0..101) or, when None, the first free one from 1 up."""
    if domain is not None:
        if not 0 <= domain <= LAST_DOMAIN:
            raise DomainInUse(f"ROS domain id must be in [0, {LAST_DOMAIN}], got {domain}")
        handle, holder = _try(domain)
        if handle is None:
            raise DomainInUse(
                f"ROS_DOMAIN_ID {domain} is in use by another bench run ({holder}); "
                "choose another --domain-id or leave it out to take a free one"
            )
        return Reservation(domain, handle)
    for candidate in range(FIRST_AUTO, LAST_DOMAIN + 1):
        handle, _ = _try(candidate)
        if handle is not None:
            return Reservation(candidate, handle)
    raise DomainInUse(f"every ROS domain id {FIRST_AUTO}..{LAST_DOMAIN} is in use by bench runs")
