import functools
import multiprocessing as mp
import os
import pathlib

import numpy as np
import pytest
import xarray as xr

from xtopo.analysis.reliability import reliability_cutoff
from xtopo.analysis.scalars import scalars
from xtopo.cache import Cache, checksum
from xtopo.conventions import height_of
from xtopo.datasets import fractal_surface
from xtopo.errors import XtopoError


_CALLS = []


def _counted(ds, **kw):
    # module level: a closure over the list would be another function once the list changed
    # (functions are keyed by content, captured values included)
    _CALLS.append(kw)
    return scalars(ds)


def test_hit_returns_identical_result_and_skips_compute(tmp_path):
    _CALLS.clear()
    ds = fractal_surface((64, 64), 1.0, hurst=0.7, seed=1)
    cache = Cache(tmp_path)
    first = cache(_counted, ds)
    second = cache(_counted, ds)
    assert len(_CALLS) == 1 and cache.hits == 1 and cache.misses == 1
    xr.testing.assert_identical(second, first)


def test_changed_data_or_parameters_recompute(tmp_path):
    cache = Cache(tmp_path)
    ds = fractal_surface((64, 64), 1.0, hurst=0.7, seed=1)
    from xtopo.analysis.distribution import distribution

    a = cache(distribution, ds, kind="height", bins=10)
    b = cache(distribution, ds, kind="height", bins=12)
    assert cache.misses == 2 and a.sizes["bin"] == 10 and b.sizes["bin"] == 12
    changed = ds.copy(deep=True)
    changed["height"][0, 0] += 1e-12
    assert checksum(changed) != checksum(ds)
    cache(distribution, changed, kind="height", bins=10)
    assert cache.misses == 3
    tipped = ds.assign_attrs(tip_radius=1e-3)
    assert checksum(tipped) != checksum(ds)
    cache(distribution, ds, kind="height", bins=10)
    assert cache.hits == 1


def _worker(directory, seed, q):
    ds = fractal_surface((128, 128), 1.0, hurst=0.7, seed=seed)
    out = Cache(directory)(scalars, ds)
    q.put(float(out.Sq))


def test_concurrent_writers_same_key(tmp_path):
    ctx = mp.get_context("spawn")
    q = ctx.Queue()
    procs = [ctx.Process(target=_worker, args=(str(tmp_path), 3, q)) for _ in range(4)]
    for p in procs:
        p.start()
    for p in procs:
        p.join(60)
    values = [q.get(timeout=5) for _ in procs]
    assert all(p.exitcode == 0 for p in procs)
    assert len(set(values)) == 1
    files = os.listdir(tmp_path)
    assert len(files) == 1 and files[0].endswith(".nc")  # one entry, no temp files left
    again = Cache(tmp_path)
    res = again(scalars, fractal_surface((128, 128), 1.0, hurst=0.7, seed=3))
    assert again.hits == 1 and float(res.Sq) == values[0]


def test_damaged_entry_is_recomputed(tmp_path):
    cache = Cache(tmp_path)
    ds = fractal_surface((32, 32), 1.0, hurst=0.7)
    cache(scalars, ds)
    with open(cache.path(scalars, ds), "wb") as f:
        f.write(b"garbage")
    res = cache(scalars, ds)
    assert cache.misses == 2 and np.isfinite(float(res.Sq))


def test_array_changed_in_place_recomputes(tmp_path):
    """The in-process layer never hides a change: an array mutated in place gets a new key."""
    cache = Cache(tmp_path)
    ds = fractal_surface((128, 128), 1.0, hurst=0.7, seed=2)
    first = cache(scalars, ds)
    assert cache(scalars, ds).Sq == first.Sq and cache.hits == 1
    ds["height"].values[5, 7] += 0.5  # same array object, new content
    changed = cache(scalars, ds)
    assert cache.misses == 2 and float(changed.Sq) != float(first.Sq)
    xr.testing.assert_identical(changed, scalars(ds))


def test_frozen_measurement_is_hashed_once_and_stays_immutable(tmp_path, monkeypatch):
    import xtopo.cache as cache_mod

    calls = []
    real = cache_mod._hash_array
    monkeypatch.setattr(cache_mod, "_hash_array", lambda a: calls.append(a.nbytes) or real(a))
    ds = fractal_surface((128, 128), 1.0, hurst=0.7, seed=4)
    frozen = cache_mod.freeze(ds)
    xr.testing.assert_identical(frozen, ds)
    with pytest.raises(ValueError):
        frozen["height"].values[0, 0] = 1.0
    with pytest.raises(ValueError):
        frozen["height"].values.flags.writeable = True
    cache = Cache(tmp_path)
    cache(scalars, frozen)
    cache(scalars, frozen)
    assert checksum(frozen) == checksum(ds) and cache.hits == 1
    big = [n for n in calls if n >= cache_mod._MEMO_MIN_BYTES]
    # frozen heights hashed once for three look-ups, writeable ones on every call
    assert big == [ds["height"].nbytes] * 2


def test_memory_copy_follows_the_file(tmp_path):
    """A hit served from memory is a private copy, and a replaced file replaces it."""
    cache = Cache(tmp_path)
    ds = fractal_surface((64, 64), 1.0, hurst=0.7, seed=5)
    first = cache(scalars, ds)
    hit = cache(scalars, ds)
    hit["Sq"] = hit["Sq"] * 0 + 123.0  # mutating what a hit returned must not reach the cache
    xr.testing.assert_identical(cache(scalars, ds), first)
    other = Cache(tmp_path, memory_bytes=0)
    assert float(other(scalars, ds).Sq) == float(first.Sq) and other.hits == 1
    assert cache.clear() == 1
    cache(scalars, ds)
    assert cache.misses == 2


def _scaled_by(k):
    def scaled(ds):
        return (scalars(ds).Sq * k).rename("scaled")
    return scaled


def test_functions_and_parameters_are_keyed_by_content(tmp_path):
    """Keys were built from the qualified name and repr(params): every lambda (and every closure of one
    factory) shared one entry, and arrays differing beyond numpy's abbreviated repr hit a stale result."""
    cache = Cache(tmp_path)
    ds = fractal_surface((32, 32), 1.0, hurst=0.7, seed=1)
    xr.testing.assert_identical(cache(lambda d: scalars(d).Sq, ds), scalars(ds).Sq)
    xr.testing.assert_identical(cache(lambda d: scalars(d).Sa, ds), scalars(ds).Sa)
    xr.testing.assert_identical(cache(_scaled_by(2.0), ds), _scaled_by(2.0)(ds))
    xr.testing.assert_identical(cache(_scaled_by(3.0), ds), _scaled_by(3.0)(ds))

    def weighted(d, *, weights):
        return (scalars(d).Sq * float(np.sum(weights))).rename("weighted")

    ones = np.ones(5000)
    other = ones.copy()
    other[2500] = 6.0  # same repr as ``ones``
    xr.testing.assert_identical(cache(weighted, ds, weights=ones), weighted(ds, weights=ones))
    xr.testing.assert_identical(cache(weighted, ds, weights=other), weighted(ds, weights=other))
    assert cache.misses == 6 and cache.hits == 0
    xr.testing.assert_identical(cache(weighted, ds, weights=other.copy()), weighted(ds, weights=other))
    assert cache.hits == 1
    import functools

    part = functools.partial(weighted, weights=other)  # a partial has no __qualname__ (was an AttributeError)
    xr.testing.assert_identical(cache(part, ds), weighted(ds, weights=other))


def _flagged(ds):
    return scalars(ds).Sq.assign_attrs(reliable=True, settings={"window": "hann"})


def test_first_result_equals_hits_and_bad_arguments_raise(tmp_path):
    """The first call returned bool/dict attrs, hits their stored form (1, JSON): a hit was not
    identical to the first result. Bad arguments raised bare TypeError/ValueError/AttributeError/
    FileExistsError (a function returning None only after computing)."""
    ds = fractal_surface((32, 32), 1.0, hurst=0.7, seed=1)
    cache = Cache(tmp_path / "c")
    first = cache(_flagged, ds)
    xr.testing.assert_identical(cache(_flagged, ds), first)
    assert cache.hits == 1 and first.attrs["reliable"] == 1 and first.attrs["settings"] == '{"window": "hann"}'
    from xtopo.errors import XtopoError

    with pytest.raises(XtopoError, match="needs an xarray Dataset or DataArray.*ndarray"):
        cache(_flagged, np.zeros((4, 4)))
    with pytest.raises(XtopoError, match="returned a NoneType"):
        cache(lambda d: None, ds)
    (tmp_path / "file").write_text("")
    with pytest.raises(XtopoError, match="cannot create the cache directory .*file"):
        Cache(tmp_path / "file")(_flagged, ds)


def test_an_edited_module_function_is_computed_again(tmp_path, monkeypatch):
    """A function defined in an importable module was keyed by its name only (dask pickles it by
    reference): after its body was edited — a reload, a new process — the cache returned the old
    code's result."""
    import importlib
    import sys

    cache = Cache(tmp_path / "cache")
    ds = fractal_surface((32, 32), 1.0, hurst=0.7, seed=1)
    source = "from xtopo.analysis.scalars import scalars\n\ndef stat(ds):\n    return scalars(ds).{}\n"
    module = tmp_path / "xtopo_cache_probe.py"
    module.write_text(source.format("Sq"))
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.delitem(sys.modules, "xtopo_cache_probe", raising=False)
    probe = importlib.import_module("xtopo_cache_probe")
    xr.testing.assert_identical(cache(probe.stat, ds), scalars(ds).Sq)
    for comment in ("# edited\n", "# edited again\n"):  # the source changes size: no stale bytecode
        module.write_text(source.format("Sa") + comment)
        probe = importlib.reload(probe)
        xr.testing.assert_identical(cache(probe.stat, ds), scalars(ds).Sa)
    assert cache.misses == 2 and cache.hits == 1  # the second edit left the code as it was: a hit
    sys.modules.pop("xtopo_cache_probe", None)


class _Scaled:
    def __init__(self, factor):
        self.factor = factor

    def __call__(self, ds):
        return scalars(ds).Sq * self.factor

    def method(self, ds):
        return scalars(ds).Sa * self.factor


@pytest.mark.parametrize("func", [np.mean, np.add, len, str, _Scaled(2.0), _Scaled(2.0).method, _counted,
                                  lambda d: d])
def test_every_kind_of_callable_has_a_stable_key(tmp_path, func):
    """Builtins, ufuncs, classes, callable instances and bound methods all key (none has Python code
    of its own, or it sits one level down), the same way twice."""
    from xtopo._tokens import callable_token

    assert callable_token(func) == callable_token(func)
    assert callable_token(func) != callable_token(functools.partial(func, 1))


@pytest.mark.parametrize("func", [None, "scalars", 3, [len]])
def test_cache_needs_a_function(tmp_path, func):
    # a bare TypeError ('NoneType' object is not callable) after the look-up
    ds = fractal_surface((8, 8), 1.0, hurst=0.7, units="um")
    with pytest.raises(XtopoError, match="Cache needs a function to call"):
        Cache(str(tmp_path))(func, ds)


# --------------------------------------------------------------------------- damaged entries (issue 24)

def _float_at(path, value: float):
    """Offset and byte order of the stored float64 ``value`` (the entry holds it once; NetCDF-3 is big-endian)."""
    raw = path.read_bytes()
    for order in "<>":
        packed = np.array(value, dtype=f"{order}f8").tobytes()
        pos = raw.find(packed)
        if pos >= 0:
            assert raw.find(packed, pos + 1) < 0
            return pos, order
    raise AssertionError("value not found in the entry")


def _flip_bit(path, value):
    pos, _ = _float_at(path, value)
    with open(path, "r+b") as f:
        f.seek(pos + 2)
        byte = f.read(1)[0]
        f.seek(pos + 2)
        f.write(bytes([byte ^ 0x10]))


def _write_nan(path, value):
    pos, order = _float_at(path, value)
    with open(path, "r+b") as f:
        f.seek(pos)
        f.write(np.full(1, np.nan, dtype=f"{order}f8").tobytes())


def _truncate(path, value):
    with open(path, "r+b") as f:
        f.truncate(os.path.getsize(path) // 2)


def _other_key(path, value):
    """Another key's valid entry copied over this one (same function, another surface)."""
    cache = Cache(path.parent, memory_bytes=0)
    other = cache(_sa_of, fractal_surface((32, 32), 1.0, hurst=0.7, seed=9))
    assert float(other) != value
    path.write_bytes(pathlib.Path(cache.path(_sa_of, fractal_surface((32, 32), 1.0, hurst=0.7, seed=9)))
                     .read_bytes())


def _sa_of(ds):
    return scalars(ds).Sa


@pytest.mark.parametrize("damage", [_flip_bit, _write_nan, _truncate, _other_key])
def test_a_damaged_or_swapped_entry_is_recomputed_and_replaced(tmp_path, damage):
    """A flipped bit, a NaN written into the stored value and another key's valid entry copied over
    were all served as hits: each entry now holds its key and a checksum of its content."""
    ds = fractal_surface((32, 32), 1.0, hurst=0.7, seed=1)
    cache = Cache(tmp_path)
    first = cache(_sa_of, ds)
    path = pathlib.Path(cache.path(_sa_of, ds))
    damage(path, float(first))
    fresh = Cache(tmp_path, memory_bytes=0)  # read from disk
    again = fresh(_sa_of, ds)
    assert fresh.misses == 1 and fresh.hits == 0
    xr.testing.assert_identical(again, first)
    later = Cache(tmp_path, memory_bytes=0)  # the entry was replaced by a good one
    xr.testing.assert_identical(later(_sa_of, ds), first)
    assert later.hits == 1
    # the in-process copy follows the file too: the cache that wrote it recomputes after damage
    damage(path, float(first))
    xr.testing.assert_identical(cache(_sa_of, ds), first)
    assert cache.misses == 2


def _mixed(ds):
    """A result with a bool map, text coords, an array attr and a DataArray-free layout."""
    s = scalars(ds)
    return xr.Dataset({"flags": (("y", "x"), np.asarray(ds.height.values > 0)),
                       "values": (("name",), np.array([float(s.Sq), float(s.Sa)]), {"units": "m"})},
                      coords={"name": ["Sq", "Sa"]}, attrs={"weights": np.array([1.0, 2.0]), "ok": True})


def _cold(directory):
    """A cache that reads from disk: the in-process copies (shared by every cache) of ``directory`` dropped."""
    import xtopo.cache as cache_module

    cache_module._memory.clear(os.path.abspath(directory))
    return Cache(directory, memory_bytes=0)


@pytest.mark.parametrize("func", [_mixed, _sa_of, scalars])
def test_every_kind_of_result_verifies_when_read_back(tmp_path, func):
    """The content checksum is taken over the stored form: valid entries of every shape are hits."""
    ds = fractal_surface((16, 16), 1.0, hurst=0.7, seed=1)
    first = Cache(tmp_path)(func, ds)
    cold = _cold(tmp_path)
    xr.testing.assert_identical(cold(func, ds), first)
    assert cold.hits == 1


def _big_count(ds):
    return xr.DataArray(np.int64(2**40) + ds.sizes["x"], name="count", attrs={"units": "1", "long_name": "Δ count"})


@pytest.mark.parametrize("func, magic", [(scalars, b"CDF"), (_big_count, b"\x89HD")])
def test_entries_are_netcdf3_unless_the_result_needs_netcdf4(tmp_path, func, magic):
    """NetCDF-3 entries are read back by scipy (pure Python, 15-25x faster cold hits than HDF5); a result that
    NetCDF-3 would change (a 64-bit integer) is stored as NetCDF-4 instead, and both verify as hits."""
    ds = fractal_surface((16, 16), 1.0, hurst=0.7, seed=1)
    first = Cache(tmp_path)(func, ds)
    path = pathlib.Path(Cache(tmp_path).path(func, ds))
    assert path.read_bytes()[:3] == magic
    cold = _cold(tmp_path)
    xr.testing.assert_identical(cold(func, ds), first)
    assert cold.hits == 1


# --------------------------------------------------------------------------- cheap hits (issue 27)

def _with_coords(ds):
    """A DataArray with an index coordinate and a non-index one (what a 1D PSD or ACF looks like, plus one)."""
    q = np.arange(5.0)
    return xr.DataArray(q * float(scalars(ds).Sq), dims="q", name="power", attrs={"units": "m3"},
                        coords={"q": ("q", q, {"units": "1/m"}), "weight": ("q", np.ones(5), {"units": "1"})})


def _two_variables(ds):
    return _with_coords(ds).to_dataset().assign(other=lambda d: d.power * 2).assign_attrs(kind="test")


@pytest.mark.parametrize("func", [_with_coords, _two_variables])
def test_changing_a_hit_in_place_never_reaches_the_cache(tmp_path, func):
    """Hits share the stored result's indexes but nothing a caller can change: values, non-index
    coordinates, and the attrs of the object, its variables and its coordinates are its own."""
    ds = fractal_surface((32, 32), 1.0, hurst=0.7, seed=1)
    cache = Cache(tmp_path)
    first = cache(func, ds).copy(deep=True)
    hit = cache(func, ds)
    xr.testing.assert_identical(hit, first)
    hit.attrs["units"] = "changed"
    hit.encoding["unlimited_dims"] = {"q"}
    hit["q"].attrs["units"] = "changed"
    hit["weight"].values[:] = -1.0
    hit["weight"].attrs["units"] = "changed"
    for name in ["power", "other"] if isinstance(hit, xr.Dataset) else [None]:
        var = hit if name is None else hit[name]
        var.values[:] = -1.0
        var.attrs["units"] = "changed"
    again = cache(func, ds)
    xr.testing.assert_identical(again, first)
    assert cache.hits == 2 and again.encoding == first.encoding


@pytest.mark.parametrize("ds_change, in_height", [
    (lambda d: d.assign_coords(x=d.x * 2), True),
    (lambda d: d.assign_coords(x=d.x.assign_attrs(units="um")), True),
    (lambda d: d.assign(height=d.height.assign_attrs(units="nm")), True),
    (lambda d: d.rename(x="u"), True),
    (lambda d: d.assign_attrs(periodic=0), False),
    (lambda d: d.assign(mask=d.height > 0), False),
    (lambda d: d.stack(p=("y", "x")), True),  # index coordinates read from pandas: a MultiIndex too
], ids=["x values", "x units", "height units", "dim name", "periodic", "mask added", "stacked"])
def test_checksum_follows_what_analyses_read(ds_change, in_height):
    """The checksum covers coordinates (values, units), dims, every variable and the measurement attrs,
    on a Dataset and on its height DataArray alike."""
    ds = fractal_surface((16, 16), 1.0, hurst=0.7, seed=1)
    changed = ds_change(ds)
    assert checksum(ds.copy(deep=True)) == checksum(ds)
    assert checksum(changed) != checksum(ds)
    assert (checksum(changed.height) != checksum(ds.height)) == in_height
    stretched = ds.assign_coords(x=ds.x * 2)
    assert checksum(ds_change(stretched)) != checksum(changed)


def test_a_tip_radius_in_other_units_keys_other_results():
    """A tip radius of 50 nm on µm data: its height DataArray read it as 50 µm (the units attr stayed behind: a
    reliability cutoff 18× too long), and the checksum of 50 nm equalled that of 50 µm (a stale cached cutoff)."""
    ds = fractal_surface((64, 64), 1.0, hurst=0.8, rms_slope=0.1, seed=1, units="um")
    in_nm = ds.assign_attrs(tip_radius=50.0, tip_radius_units="nm")
    in_um = ds.assign_attrs(tip_radius=0.05, tip_radius_units="um")
    assert float(reliability_cutoff(height_of(in_nm))) == float(reliability_cutoff(in_um))
    assert checksum(in_nm) != checksum(in_nm.assign_attrs(tip_radius_units="um"))


def test_parameters_are_keyed_by_value_and_type(tmp_path):
    """Plain parameters are keyed by their repr: 1, 1.0, True, '1' and None give different entries, numpy
    scalars and arrays (keyed by dask's tokenize) others again, and the same values the same entry."""
    cache = Cache(tmp_path)
    ds = fractal_surface((16, 16), 1.0, hurst=0.7, seed=1)
    values = [1, 1.0, True, "1", None, 2, -0.0, 0.0, float("nan"), np.float64(1.0), np.int64(1), np.ones(3)]
    paths = [cache.path(_counted, ds, x=v) for v in values]
    assert len(set(paths)) == len(values)
    assert paths == [cache.path(_counted, ds, x=v) for v in values]
    assert cache.path(_counted, ds, a=1, b="x") == cache.path(_counted, ds, b="x", a=1)
    assert cache.path(_counted, ds, a=1, b="x") != cache.path(_counted, ds, a="x", b=1)


def test_datetime_variables_are_checksummed_and_cached(tmp_path):
    """A datetime64 coordinate or variable raised ValueError (numpy gives datetimes no buffer to hash)."""
    import pandas as pd

    def timed(start):
        return xr.Dataset({"v": ("t", [1.0, 2.0]), "when": ("t", pd.date_range(start, periods=2).values)},
                          coords={"t": pd.date_range(start, periods=2)})

    assert checksum(timed("2020")) == checksum(timed("2020")) != checksum(timed("2021"))
    cache = Cache(tmp_path)
    assert float(cache(_total, timed("2020"))) == 3.0
    assert float(cache(_total, timed("2020"))) == 3.0 and cache.hits == 1
    assert float(cache(_total, timed("2021"))) == 3.0 and cache.misses == 2


def _total(ds):
    return ds.v.sum()


def _pair(ds):
    _CALLS.append("pair")
    return scalars(ds), None


def test_remember_keeps_results_in_memory_and_returns_private_copies():
    """remember: no file; the same data, function and ``also`` computed once, each caller its own copy."""
    from xtopo.cache import remember

    _CALLS.clear()
    ds = fractal_surface((32, 32), 1.0, hurst=0.7, seed=3)
    first, none = remember(_pair, ds, "a")
    first["Sq"].values[...] = -1.0
    again, _ = remember(_pair, ds.copy(deep=True), "a")
    assert none is None and len(_CALLS) == 1 and float(again["Sq"]) > 0
    xr.testing.assert_identical(again, scalars(ds))
    remember(_pair, ds, "b")
    remember(_pair, ds.assign_attrs(tip_radius=1e-3), "a")
    assert len(_CALLS) == 3
