"""Hostile input: truncated, corrupted, empty and misnamed copies of every real file.

Each read must end within :data:`READ_TIMEOUT` seconds with either a valid Dataset or an
:class:`~xtopo.errors.XtopoError` whose message names the file — never another exception
type, a hang, a crash (segfault) or a multi-GB allocation. Reads run in worker processes
(readers may go through C libraries) with an address-space limit (``RLIMIT_AS``), so a crash
or a runaway allocation is caught instead of taking the test run down; the parent enforces
the per-read timeout and restarts a worker after a crash or hang.

The default suite runs a reduced set (3 truncations, 10 corruptions per file); the full set
(12 truncations, 200 corruptions per file) is marked ``slow``. Run it alone with
``python -m pytest tests/io/test_hostile_input.py -m slow -s`` (prints a summary).
"""

from __future__ import annotations

import json
import os
import pathlib
import queue
import subprocess
import sys
import threading
import time
from concurrent.futures import ThreadPoolExecutor

import pytest

REPO = pathlib.Path(__file__).resolve().parents[2]
READ_TIMEOUT = 10.0  # seconds per read
STARTUP_TIMEOUT = 90.0  # import of xtopo and its dependencies in a fresh worker
ADDRESS_SPACE = int(2.5 * 1024 ** 3)  # bytes; a reader needing more is a failure

pytestmark = pytest.mark.real_data


# ----------------------------------------------------------------------------- jobs

def make_jobs(files, n_trunc: int, n_corrupt: int, seed: int = 0) -> list[dict]:
    """The deterministic list of mutations: truncations, corruptions, empty file, wrong suffix."""
    import numpy as np

    jobs = []
    for f in files:
        size = os.path.getsize(f)
        offsets = {int(v) for v in np.linspace(0, size, n_trunc + 2)[1:-1]}
        if n_trunc >= 10:
            offsets |= {1, 8, 100, 1024}  # inside the magic bytes and the header
        jobs += [{"src": str(f), "kind": "truncate", "offset": o} for o in sorted(offsets) if 0 < o < size]
        jobs += [{"src": str(f), "kind": "corrupt", "seed": seed * 100003 + k} for k in range(n_corrupt)]
        jobs.append({"src": str(f), "kind": "empty"})
        jobs.append({"src": str(f), "kind": "suffix"})
    return jobs


def mutate(job: dict, tmpdir: str) -> str:
    """Write the mutated copy of ``job['src']`` under ``tmpdir``; return its path."""
    import numpy as np

    src = pathlib.Path(job["src"])
    data = src.read_bytes()
    name = src.name
    if job["kind"] == "truncate":
        data = data[:job["offset"]]
    elif job["kind"] == "corrupt":
        rng = np.random.default_rng(job["seed"])
        buf = bytearray(data)
        n = int(rng.integers(1, 9))
        # half the corruptions hit the first 4 KiB, where headers and size fields live
        limit = len(buf) if rng.random() < 0.5 else min(len(buf), 4096)
        for pos in rng.integers(0, limit, n):
            buf[int(pos)] = int(rng.integers(0, 256))
        data = bytes(buf)
    elif job["kind"] == "empty":
        data = b""
    elif job["kind"] == "suffix":
        name = src.stem + (".sdf" if src.suffix.lower() == ".txt" else ".txt")
    path = os.path.join(tmpdir, f"{job['kind']}-{name}")
    with open(path, "wb") as f:
        f.write(data)
    return path


# ----------------------------------------------------------------------------- worker side

def worker_main() -> None:
    """Read jobs (JSON on stdin) and print one JSON result line per job."""
    import resource
    import tempfile
    import traceback

    resource.setrlimit(resource.RLIMIT_AS, (ADDRESS_SPACE, ADDRESS_SPACE))
    import xtopo
    from xtopo.errors import XtopoError

    jobs = json.loads(sys.stdin.readline())
    with tempfile.TemporaryDirectory() as warm:  # first-use costs (format modules, unit registry) before timing
        probe = os.path.join(warm, "warm-up.txt")
        with open(probe, "w") as f:
            f.write("# Width: 1 um\n# Height: 1 um\n# Value units: nm\n1 2\n3 4\n")
        xtopo.open_topography(probe)
    print(json.dumps({"ready": True}), flush=True)
    with tempfile.TemporaryDirectory() as tmp:
        for job in jobs:
            path = mutate(job, tmp)
            t0 = time.perf_counter()
            res = {"i": job["i"]}
            try:
                ds = xtopo.open_topography(path)
                xtopo.validate(ds)
                res["status"] = "ok"
            except XtopoError as exc:
                msg = str(exc)
                if "MemoryError" in msg:
                    res["status"] = "alloc"
                elif os.path.basename(path) not in msg:
                    res["status"] = "unnamed"
                else:
                    res["status"] = "error"
                res["type"] = type(exc).__name__
                res["msg"] = msg[-300:]
            except BaseException as exc:  # noqa: BLE001  what the harness exists to catch
                res["status"] = "alloc" if isinstance(exc, MemoryError) else "foreign"
                res["type"] = type(exc).__name__
                res["msg"] = "".join(traceback.format_exception_only(exc))[-300:]
            res["secs"] = time.perf_counter() - t0
            os.unlink(path)
            print(json.dumps(res), flush=True)


# ----------------------------------------------------------------------------- parent side

def _spawn():
    code = (f"import sys; sys.path.insert(0, {str(REPO)!r}); sys.path.insert(0, {str(pathlib.Path(__file__).parent)!r});"
            "import test_hostile_input as w; w.worker_main()")
    env = {**os.environ, "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1",
           "PYTHONWARNINGS": "ignore"}
    proc = subprocess.Popen([sys.executable, "-c", code], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                            stderr=subprocess.DEVNULL, text=True, cwd=str(REPO), env=env)
    lines: queue.Queue = queue.Queue()

    def pump():
        for line in proc.stdout:
            lines.put(line)
        lines.put(None)

    threading.Thread(target=pump, daemon=True).start()
    return proc, lines


def run_jobs(jobs: list[dict]) -> list[dict]:
    """Run ``jobs`` in a worker; restart it after a crash or a hang. One result per job."""
    jobs = [{**j, "i": i} for i, j in enumerate(jobs)]
    results: list[dict] = []
    start = 0
    while start < len(jobs):
        proc, lines = _spawn()
        proc.stdin.write(json.dumps(jobs[start:]) + "\n")
        proc.stdin.flush()
        try:
            first = lines.get(timeout=STARTUP_TIMEOUT)
        except queue.Empty:
            first = None
        if not first or "ready" not in first:
            proc.kill()
            proc.wait()
            raise RuntimeError("the hostile-input worker did not start")
        i = start
        while i < len(jobs):
            try:
                line = lines.get(timeout=READ_TIMEOUT)
            except queue.Empty:
                results.append({**jobs[i], "status": "hang", "secs": READ_TIMEOUT})
                proc.kill()
                break
            if line is None:  # the worker died: a crash, or the kernel killed it
                proc.wait()
                results.append({**jobs[i], "status": "crash", "returncode": proc.returncode})
                break
            res = json.loads(line)
            results.append({**jobs[i], **res})
            i += 1
        proc.kill()
        proc.wait()
        start = i + 1 if i < len(jobs) else i
    return results


FAILING = ("hang", "crash", "foreign", "unnamed", "alloc")


def _summary(results):
    by = {}
    for r in results:
        by.setdefault(pathlib.Path(r["src"]).name, {}).setdefault(r["status"], 0)
        by[pathlib.Path(r["src"]).name][r["status"]] += 1
    slowest = max(results, key=lambda r: r.get("secs", 0))
    return by, slowest


def _real_files(real_data):
    return sorted(p for p in real_data.iterdir() if p.is_file() and p.name != "MANIFEST.md")


def check_results(results, expected):
    assert len(results) == expected
    bad = [r for r in results if r["status"] in FAILING]
    assert not bad, "hostile-input failures:\n" + "\n".join(
        f"{pathlib.Path(r['src']).name} {r['kind']} {r.get('offset', r.get('seed', ''))}: {r['status']} "
        f"{r.get('type', '')} {r.get('msg', '')}" for r in bad[:20])
    assert max(r["secs"] for r in results) < READ_TIMEOUT


def test_hostile_input_reduced(real_data):
    files = _real_files(real_data)
    jobs = make_jobs(files, n_trunc=3, n_corrupt=10)
    results = run_jobs(jobs)
    check_results(results, len(jobs))
    # the unmodified text formats still read; their empty copies are refused with a named error
    assert all(r["status"] == "error" for r in results if r["kind"] == "empty")


@pytest.mark.slow
def test_hostile_input_full(real_data):
    files = _real_files(real_data)
    t0 = time.perf_counter()
    with ThreadPoolExecutor(max_workers=2) as pool:  # one worker process per file, two at a time
        per_file = list(pool.map(lambda f: run_jobs(make_jobs([f], n_trunc=12, n_corrupt=200, seed=1)), files))
    results = [r for rs in per_file for r in rs]
    by, slowest = _summary(results)
    print(f"\nhostile input: {len(results)} reads of {len(files)} files in {time.perf_counter() - t0:.0f} s; "
          f"slowest read {slowest['secs']:.2f} s ({pathlib.Path(slowest['src']).name} {slowest['kind']})")
    for name, counts in sorted(by.items()):
        print(f"  {name:40s} {counts}")
    check_results(results, sum(len(make_jobs([f], 12, 200, 1)) for f in files))
