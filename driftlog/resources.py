"""Memory estimates made before allocating.

A run too large is refused in a second, not after minutes with a ``MemoryError`` and a
half-written file.
"""

from __future__ import annotations

import os

from driftlog.errors import SizeError

__all__ = ["available_memory", "check_fits"]


def available_memory() -> int:
    """Bytes of memory available to this process (MemAvailable, else physical memory)."""
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):  # pragma: no cover - not POSIX
        return 8 << 30


def check_fits(nbytes: float, what: str, advice: str, fraction: float = 0.5) -> float:
    """Raise ``SizeError`` if ``nbytes`` exceeds ``fraction`` of the available memory.

    Parameters
    ----------
    nbytes : float
        Estimated bytes the task needs.
    what : str
        The task and its size, for the message (e.g. ``"tracking 1e7 logs"``).
    advice : str
        What to change.
    fraction : float
        Share of the available memory a task may take.
    """
    avail = available_memory()
    if nbytes > fraction * avail:
        raise SizeError(f"{what} needs about {nbytes / 2**30:.3g} GiB of memory, more than "
                        f"{fraction:.0%} of the {avail / 2**30:.3g} GiB available; {advice}")
    return nbytes
