"""Damaged NetCDF-3 and NetCDF-4/HDF5 files cannot crash, hang or exhaust the reader (issue 24).

Mutants of xtopo's own archives (``xtopo.to_netcdf`` with both engines, the SurfaceTopography export,
a twin archive, a contact result, a cache entry) are read in a child process through xtopo's entry
points, so that a crash (SIGSEGV inside a C library) is detected instead of ending the test run.
After each damaged file the child reads a good one and collects garbage: one crash of netCDF-C came
only at the next garbage collection, after a later good file.

The default suite keeps fixed reproducers, generated here from a good file: a NetCDF-3 header whose
dimension count reads 2**31 (``netCDF4.Dataset`` dies with SIGSEGV on it; xtopo reached it through
the SurfaceTopography reader's engine fallback) and headers claiming huge lengths (scipy allocated up
to 16 GB for them). The seeded fuzz run over all sources is in the slow suite.
"""

from __future__ import annotations

import json
import os
import struct
import subprocess
import sys
import textwrap

import numpy as np
import pytest

import xtopo
from xtopo.datasets import fractal_surface

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
#: a child that reads must stay below this much resident memory above its start (MB)
MEMORY_BOUND_MB = 400
#: seconds one read (a damaged file, then a good one) may take before it counts as a hang; reads take
#: milliseconds, the margin is for a loaded machine
READ_TIMEOUT = 120

_WORKER = textwrap.dedent("""
    import gc, json, resource, sys, warnings
    sys.path.insert(0, {repo!r})
    import xtopo
    from xtopo.io.netcdf import read_netcdf
    warnings.simplefilter("ignore")
    jobs = json.loads(sys.stdin.read())
    read = {{"measurement": xtopo.open_topography, "twin": xtopo.twins.open_twin, "archive": read_netcdf}}
    for kind, path, good in jobs[:1]:
        read[kind](good)  # first-use costs (imports, unit registry) before the baseline
    base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    for kind, path, good in jobs:
        try:
            read[kind](path)
            status = "ok"
        except xtopo.XtopoError as exc:
            status = "refused" if path in str(exc) else "unnamed: " + str(exc)[:200]
        except BaseException as exc:  # what the harness exists to catch
            status = "foreign: " + type(exc).__name__ + ": " + str(exc)[:200]
        read[kind](good)  # a crash left for later (at the next collection) shows here
        gc.collect()
        print(json.dumps([path, status]), flush=True)
    print(json.dumps(["__memory__", (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - base) / 1024]), flush=True)
""").format(repo=REPO)


def read_in_children(jobs):
    """Read ``jobs`` (kind, path, good path) in child processes; ``({path: status}, peak MB)``.

    A child that dies (a signal) marks the file it was reading as ``crash``; one that reports nothing
    for :data:`READ_TIMEOUT` seconds is killed and the file marked ``hang``; the remaining files go to
    a fresh child.
    """
    import queue
    import threading

    results, peak = {}, 0.0
    todo = list(jobs)
    while todo:
        proc = subprocess.Popen([sys.executable, "-c", _WORKER], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                stderr=subprocess.DEVNULL, text=True)
        lines = queue.Queue()
        threading.Thread(target=lambda: [lines.put(x) for x in proc.stdout] + [lines.put(None)], daemon=True).start()
        proc.stdin.write(json.dumps(todo))
        proc.stdin.close()
        done, status = 0, None
        while True:
            try:
                line = lines.get(timeout=READ_TIMEOUT * (3 if done == 0 else 1))  # the first includes imports
            except queue.Empty:
                proc.kill()
                status = "hang"
                break
            if line is None:
                break
            path, value = json.loads(line)
            if path == "__memory__":
                peak = max(peak, value)
            else:
                results[path] = value
                done += 1
        rc = proc.wait()
        if status is None and rc == 0:
            break
        if done >= len(todo):  # died after its last report: while collecting garbage or exiting
            results[todo[-1][1]] = f"crash at exit ({rc})"
            break
        results[todo[done][1]] = status or f"crash ({rc})"
        todo = todo[done + 1:]
    return results, peak


@pytest.fixture(scope="module")
def netcdf3_file(tmp_path_factory):
    """A measurement written as NetCDF-3 (64-bit offset)."""
    path = str(tmp_path_factory.mktemp("netcdf3") / "m3.nc")
    fractal_surface((24, 32), 1e-5, hurst=0.8, rms_height=1e-7, seed=1).to_netcdf(path, format="NETCDF3_64BIT",
                                                                                   engine="scipy")
    return path


@pytest.fixture(scope="module")
def sources(tmp_path_factory, netcdf3_file):
    """xtopo's own archives: {name: (kind, path)}."""
    from xtopo.analysis.scalars import scalars
    from xtopo.cache import Cache
    from xtopo.contact import Scene
    from xtopo.io.formats.st_netcdf import to_surfacetopography_netcdf

    d = tmp_path_factory.mktemp("sources")
    ds = fractal_surface((24, 32), 1e-5, hurst=0.8, rms_height=1e-7, seed=1)
    out = {}
    for engine in ("netcdf4", "h5netcdf"):
        out[f"measurement-{engine}"] = ("measurement", xtopo.to_netcdf(ds, d / f"m-{engine}.nc", engine=engine))
    out["measurement-netcdf3"] = ("measurement", netcdf3_file)
    out["surfacetopography"] = ("measurement", to_surfacetopography_netcdf(ds, d / "st.nc"))
    tree = xtopo.twins.twin({"a": ds, "b": fractal_surface((64,), 1e-5, hurst=0.8, rms_height=1e-7, seed=2)})
    out["twin"] = ("twin", xtopo.twins.to_netcdf(tree, d / "twin.nc"))
    periodic = fractal_surface((16, 16), 1e-5, hurst=0.8, rms_height=1e-7, seed=3, periodic=True)
    out["contact"] = ("archive", xtopo.to_netcdf(Scene(periodic).solve(mean_pressure=0.01), d / "contact.nc"))
    cache = Cache(d / "cache")
    cache(scalars, ds)
    out["cache-entry"] = ("archive", cache.path(scalars, ds))
    return {k: (kind, str(p)) for k, (kind, p) in out.items()}


def _header_int(raw: bytes, pos: int, value: int) -> bytes:
    buf = bytearray(raw)
    buf[pos:pos + 4] = struct.pack(">I", value)
    return bytes(buf)


def mutants(raw: bytes, rng, n: int):
    """``n`` damaged copies of ``raw``: truncations, overwritten bytes, header fields set to huge values."""
    for _ in range(n):
        kind = rng.integers(0, 4)
        buf = bytearray(raw)
        if kind == 0:
            yield bytes(buf[:int(rng.integers(1, len(buf)))])
            continue
        if kind == 3:  # a 4-byte field of the header (NetCDF-3) or superblock/object headers (HDF5)
            pos = int(rng.integers(0, min(len(buf), 1024) // 4)) * 4
            value = int(rng.choice([0x7FFFFFF0, 0x10000000, 0xFFFFFFFF, 0x80000000]))
            yield _header_int(raw, pos, value)
            continue
        for _ in range(int(rng.integers(1, 6))):
            pos = int(rng.integers(0, len(buf)))
            width = int(rng.integers(1, 9))
            buf[pos:pos + width] = rng.integers(0, 256, size=len(buf[pos:pos + width]), dtype=np.uint8).tobytes()
        yield bytes(buf)


def _check(results, peak, what):
    bad = {os.path.basename(p): s for p, s in results.items() if s not in ("ok", "refused")}
    assert not bad, f"{what}: {len(bad)} of {len(results)} reads crashed, hung or raised a foreign error: {bad}"
    assert peak < MEMORY_BOUND_MB, f"{what}: a reader took {peak:.0f} MB"
    return sum(s == "refused" for s in results.values())


def _netcdf3_reproducers(raw: bytes):
    """Header fields of a NetCDF-3 file set to huge values (byte offsets of the 64-bit offset layout)."""
    return {
        "dimension-count": _header_int(raw, 12, 0x7FFFFFF0),  # netCDF-C: SIGSEGV
        "name-length": _header_int(raw, 16, 0x7FFFFFF0),  # scipy: 2 GB asked for
        "dimension-length": _header_int(raw, 36, 0x7FFFFFF0),  # scipy: 16 GB asked for
        "attribute-count": _header_int(raw, 68, 0x10000000),
    }


def test_fixed_netcdf3_reproducers_are_refused_without_crash_or_allocation(netcdf3_file, tmp_path):
    kind, good = "measurement", netcdf3_file
    raw = open(good, "rb").read()
    assert raw[:4] == b"CDF\x02" and raw[12:16] == b"\x00\x00\x00\x02"  # the layout the offsets assume
    jobs = []
    for name, data in _netcdf3_reproducers(raw).items():
        path = tmp_path / f"{name}.nc"
        path.write_bytes(data)
        jobs.append((kind, str(path), good))
    results, peak = read_in_children(jobs)
    _check(results, peak, "NetCDF-3 reproducers")
    assert set(results.values()) == {"refused"}


def test_the_netcdf3_crash_reproducer_is_refused_before_any_library_sees_it(netcdf3_file, tmp_path):
    """In process: the header check refuses it, so no engine fallback can hand it to netCDF-C."""
    raw = open(netcdf3_file, "rb").read()
    path = tmp_path / "dimension-count.nc"
    path.write_bytes(_netcdf3_reproducers(raw)["dimension-count"])
    with pytest.raises(xtopo.ReaderError, match="damaged NetCDF-3 header.*dimension list"):
        xtopo.open_topography(path)


def test_damaged_hdf5_archives_are_read_with_h5py_not_netcdf_c(sources, tmp_path, monkeypatch):
    """Every NetCDF-4 read path of xtopo goes through h5netcdf: netCDF4.Dataset is never called."""
    import netCDF4

    def forbidden(*args, **kwargs):
        raise AssertionError("netCDF4.Dataset opened an untrusted file")

    monkeypatch.setattr(netCDF4, "Dataset", forbidden)
    for name, (kind, path) in sources.items():
        read = {"measurement": xtopo.open_topography, "twin": xtopo.twins.open_twin,
                "archive": xtopo.io.netcdf.read_netcdf}[kind]
        read(path)
        raw = open(path, "rb").read()
        damaged = tmp_path / f"{name}-truncated.nc"
        damaged.write_bytes(raw[: len(raw) * 2 // 3])
        with pytest.raises(xtopo.XtopoError):
            read(damaged)


@pytest.mark.slow
def test_seeded_mutants_of_xtopo_archives_never_crash_hang_or_exhaust_memory(sources, tmp_path):
    """120 mutants of each archive: 0 crashes, 0 hangs, peak memory bounded (measured: reading with the netCDF4
    library instead crashed on NetCDF-3 header mutants)."""
    rng = np.random.default_rng(24)
    jobs = []
    for name, (kind, good) in sources.items():
        raw = open(good, "rb").read()
        for i, data in enumerate(mutants(raw, rng, 120)):
            path = tmp_path / f"{name}-{i:03d}.nc"
            path.write_bytes(data)
            jobs.append((kind, str(path), good))
    results, peak = read_in_children(jobs)
    counts = {s: sum(v == s for v in results.values()) for s in set(results.values())}
    print(f"\n{len(results)} mutant reads: {counts}; peak {peak:.0f} MB above the child's start")
    assert len(results) == len(jobs)
    assert _check(results, peak, "mutants") > 0  # the mutants reached the checks (840 reads: 638 refused)
