"""Timing helpers shared by the benchmark scripts (medians and spread, never single runs)."""

from __future__ import annotations

import statistics
import subprocess
import sys
import time


def times(fn, repeat: int) -> list[float]:
    """Sorted wall times (s) of ``repeat`` runs of ``fn()`` after one warm-up call (plans, caches, imports)."""
    fn()
    out = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        out.append(time.perf_counter() - t0)
    return sorted(out)


def median_time(fn, repeat: int) -> float:
    """Median wall time of ``fn()`` over ``repeat`` runs after one warm-up call."""
    return statistics.median(times(fn, repeat))


def spread(ts) -> str:
    """``median [min–max]`` of wall times in seconds."""
    ts = sorted(ts)
    return f"{statistics.median(ts):.4f} [{ts[0]:.4f}–{ts[-1]:.4f}]"


def fresh_process_seconds(args: list[str], repeat: int) -> list[tuple[float, ...]]:
    """The numbers (seconds) on the last line of stdout of each of ``repeat`` fresh Python processes running
    ``args``, in the order they ran."""
    return [tuple(float(v) for v in subprocess.run([sys.executable, *args], check=True, capture_output=True,
                                                   text=True).stdout.splitlines()[-1].split())
            for _ in range(repeat)]
