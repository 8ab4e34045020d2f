"""Process settings for dask workers, shared by batch tasks and the twin averages' per-measurement tasks."""

from __future__ import annotations

import functools
import os

__all__ = ["tune_malloc"]


@functools.cache  # once a process
def tune_malloc() -> None:
    """Undo the cost of distributed's ``MALLOC_TRIM_THRESHOLD_`` in a worker process (glibc only, once).

    Dask's nanny starts workers with ``MALLOC_TRIM_THRESHOLD_=65536``; glibc then also
    freezes the mmap threshold at 128 KiB, so every FFT-sized temporary is a fresh
    ``mmap`` + page faults: FFT-bound work ran 2-4× slower in a worker than in a plain
    process on the reference machine. Raising both thresholds (64 MiB mmap, 128 MiB trim)
    restores plain-process speed. Set ``XTOPO_BATCH_MALLOC_TUNE=0`` to leave malloc alone.
    """
    if os.environ.get("XTOPO_BATCH_MALLOC_TUNE", "1") == "0" or "MALLOC_TRIM_THRESHOLD_" not in os.environ:
        return
    try:
        import ctypes

        libc = ctypes.CDLL("libc.so.6")
        libc.mallopt(-3, 64 << 20)  # M_MMAP_THRESHOLD
        libc.mallopt(-1, 128 << 20)  # M_TRIM_THRESHOLD
    except (OSError, AttributeError):  # not glibc: nothing to undo
        pass
