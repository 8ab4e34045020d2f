"""Startup time of ``import xtopo``, ``xtopo --version`` and ``xtopo --help`` (issue 26), as whole processes.

Each command runs ``--runs`` times in turn with the others (A B C A B C …, so drift of a shared
machine hits all alike) after one warm-up; min / median / max wall seconds are printed, with a
bare ``python -c pass`` for the interpreter's own share. ``--against DIR`` times another checkout
(e.g. the main branch) in the same rounds, with the median ratio.

Targets on the 2-core development machine: ``import xtopo`` < 0.8 s, ``--version``/``--help`` < 0.5 s
(medians). No test asserts a time; tests/test_startup.py checks which modules an import loads.

    python benchmarks/bench_startup.py [--runs 15] [--against ../main]
"""

from __future__ import annotations

import argparse
import os
import pathlib
import statistics
import subprocess
import sys
import time

REPO = pathlib.Path(__file__).resolve().parents[1]
COMMANDS = {
    "python -c pass": ["-c", "pass"],
    "import xtopo": ["-c", "import xtopo"],
    "xtopo --version": ["-m", "xtopo", "--version"],
    "xtopo --help": ["-m", "xtopo", "--help"],
}


def _once(args, checkout) -> float:
    env = {**os.environ, "PYTHONPATH": str(checkout)}
    t = time.perf_counter()
    subprocess.run([sys.executable, *args], env=env, cwd=checkout, stdout=subprocess.DEVNULL, check=True)
    return time.perf_counter() - t


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--runs", type=int, default=15)
    p.add_argument("--against", type=pathlib.Path, default=None, help="another checkout to time alongside")
    args = p.parse_args(argv)
    checkouts = {"this": REPO} | ({"against": args.against.resolve()} if args.against else {})
    times = {(c, name): [] for c in checkouts for name in COMMANDS}
    for c, path in checkouts.items():  # warm-up (file system cache, .pyc files)
        for cmd in COMMANDS.values():
            _once(cmd, path)
    for _ in range(args.runs):
        for c, path in checkouts.items():
            for name, cmd in COMMANDS.items():
                times[c, name].append(_once(cmd, path))
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"{args.runs} runs each, load average {load:.2f}, {os.cpu_count()} CPUs; wall seconds min / median / max")
    for name in COMMANDS:
        for c in checkouts:
            t = times[c, name]
            line = f"{name:18s} {c:8s} {min(t):6.3f} {statistics.median(t):6.3f} {max(t):6.3f}"
            if c == "this" and "against" in checkouts:
                ratios = [a / b for a, b in zip(t, times["against", name])]
                line += f"   this/against median ratio {statistics.median(ratios):.2f}"
            print(line)


if __name__ == "__main__":
    main()
