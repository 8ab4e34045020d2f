import errno
import hashlib
import os
import re

import numpy as np
import pytest
import xarray as xr

import xtopo
from xtopo.io.netcdf import sanitize_attrs


def _measurement():
    ds = xtopo.datasets.measure(xtopo.datasets.fractal_surface((64, 48), (1e-6, 7.5e-7), hurst=0.7, periodic=False),
                                tip_radius=1e-8, missing_fraction=0.1, seed=2)
    ds.attrs.update(instrument="AFM", flag=True, settings={"mode": "tapping", "gain": 2})
    return ds


@pytest.mark.parametrize("engine", ["netcdf4", "h5netcdf"])
def test_round_trip_is_exact(tmp_path, engine):
    ds = _measurement()
    path = tmp_path / f"m-{engine}.nc"
    xtopo.to_netcdf(ds, path, engine=engine)
    back = xtopo.open_topography(path)
    # values, coords, mask and every original attribute survive
    np.testing.assert_array_equal(back.height.values, ds.height.values)
    xr.testing.assert_identical(back.mask, ds.mask)
    xr.testing.assert_identical(back.x, ds.x)
    for key, value in sanitize_attrs(ds.attrs).items():
        np.testing.assert_equal(back.attrs[key], value)
    assert back.attrs["settings"] == '{"gain": 2, "mode": "tapping"}'
    # CF/ACDD and provenance
    assert back.attrs["Conventions"] == "CF-1.12, ACDD-1.3"
    assert back.attrs["xtopo_version"] == xtopo.__version__
    assert "date_created" in back.attrs
    # a second round trip of what was read is identical (nothing drifts)
    xtopo.to_netcdf(back, tmp_path / "again.nc", engine=engine)
    xr.testing.assert_identical(xtopo.open_topography(tmp_path / "again.nc"), back)
    # and xarray's own reader, through the entry point, sees the same data
    via_xr = xr.open_dataset(path, engine="xtopo")
    xr.testing.assert_identical(via_xr, back)


def test_engines_agree(tmp_path):
    ds = _measurement()
    a = xtopo.open_topography(xtopo.to_netcdf(ds, tmp_path / "a.nc", engine="netcdf4"))
    b = xtopo.open_topography(xtopo.to_netcdf(ds, tmp_path / "b.nc", engine="h5netcdf"))
    xr.testing.assert_identical(a.drop_attrs(), b.drop_attrs())


def test_failed_write_leaves_existing_file_intact(tmp_path, monkeypatch):
    path = tmp_path / "keep.nc"
    ds = _measurement()
    xtopo.to_netcdf(ds, path)
    before = path.read_bytes()

    original = xr.Dataset.to_netcdf

    def write_half_then_fail(self, target, *args, **kwargs):
        original(self, target, *args, **kwargs)
        with open(target, "r+b") as f:  # the temp file is half-overwritten, then the process "dies"
            f.truncate(100)
        raise OSError("disk full")

    monkeypatch.setattr(xr.Dataset, "to_netcdf", write_half_then_fail)
    with pytest.raises(xtopo.WriteError, match=f"cannot write {re.escape(str(path))}: disk full"):
        xtopo.to_netcdf(ds.assign(height=ds.height * 2), path)
    monkeypatch.undo()
    assert path.read_bytes() == before
    assert os.listdir(tmp_path) == ["keep.nc"]  # no temp file left behind
    xr.testing.assert_identical(xtopo.open_topography(path).mask, ds.mask)


def test_unencodable_attrs_are_sanitised():
    out = sanitize_attrs({"a": True, "b": None, "c": {"k": 1}, "d": ["x", "y"], "e": np.array([True, False])})
    assert out == {"a": 1, "c": '{"k": 1}', "d": '["x", "y"]', "e": out["e"]}
    assert out["e"].dtype == np.int8


def test_reading_garbage_names_the_file(tmp_path):
    bad = tmp_path / "bad.nc"
    bad.write_bytes(b"CDF\x01" + b"\xff" * 50)
    with pytest.raises(xtopo.ReaderError, match="bad.nc"):
        xtopo.open_topography(bad)
    empty = tmp_path / "empty.nc"
    empty.write_bytes(b"")
    with pytest.raises(xtopo.ReaderError, match="empty"):
        xtopo.open_topography(empty)
    with pytest.raises(xtopo.ReaderError, match="no such file"):
        xtopo.open_topography(tmp_path / "missing.nc")


@pytest.mark.parametrize("attrs, heights, problem", [
    ({"periodic": "yes"}, None, "periodic"),
    ({"tip_radius": "abc"}, None, "tip_radius"),
    ({"periodic": np.array([1, 0])}, None, "periodic"),
    ({}, np.array([["a", "b"], ["c", "d"]]), "real numbers"),
])
def test_bad_attrs_or_heights_in_netcdf_raise_reader_error(tmp_path, attrs, heights, problem):
    """A NetCDF file with a non-numeric 'periodic'/'tip_radius' attr used to crash validate()
    with a bare ValueError/TypeError; string heights were returned as a measurement."""
    h = np.zeros((2, 2)) if heights is None else heights
    path = tmp_path / "odd.nc"
    xr.Dataset({"height": (("y", "x"), h, {"units": "m"})}, attrs=attrs,
               coords={"x": ("x", [0.0, 1.0], {"units": "m"}), "y": ("y", [0.0, 1.0], {"units": "m"})}
               ).to_netcdf(path)
    with pytest.raises(xtopo.ReaderError, match=f"odd.nc.*{problem}"):
        xtopo.open_topography(path)


@pytest.mark.parametrize("engine", ["netcdf4", "h5netcdf"])
def test_attrs_netcdf_cannot_hold_are_stored_readably(tmp_path, engine):
    """numpy str, integers beyond 64 bits, nested lists and 2D arrays raised bare TypeError/ValueError
    (netcdf4), or wrote a file no reader could open again (h5netcdf, nested list)."""
    ds = _measurement()
    ds.attrs.update(operator=np.str_("Zoë"), serial=2**70, grid_pts=[[1, 2], [3, 4]], matrix=np.eye(2))
    ds.height.attrs["calibration"] = [[1.5, 0.0], [0.0, 2.5]]
    path = tmp_path / "odd-attrs.nc"
    xtopo.to_netcdf(ds, path, engine=engine)
    back = xtopo.open_topography(path)
    assert back.attrs["operator"] == "Zoë"
    assert back.attrs["serial"] == str(2**70)
    assert back.attrs["grid_pts"] == "[[1, 2], [3, 4]]"
    assert back.attrs["matrix"] == "[[1.0, 0.0], [0.0, 1.0]]"
    assert back.height.attrs["calibration"] == "[[1.5, 0.0], [0.0, 2.5]]"
    np.testing.assert_array_equal(back.height.values, ds.height.values)


def test_bad_write_arguments_raise_xtopo_errors(tmp_path):
    """path=None/int raised a bare TypeError, compress='no' compressed, complex data raised a bare ValueError."""
    ds = _measurement()
    with pytest.raises(xtopo.XtopoError, match="path must be a file path.*int"):
        xtopo.to_netcdf(ds, 3)
    with pytest.raises(xtopo.XtopoError, match="compress must be True or False, got 'no'"):
        xtopo.to_netcdf(ds, tmp_path / "c.nc", compress="no")
    cplx = xr.Dataset({"spectrum": ("q", np.array([1 + 2j, 3j]))})
    with pytest.raises(xtopo.ValidationError, match="cannot write .*complex.nc.*complex"):
        xtopo.to_netcdf(cplx, tmp_path / "complex.nc", engine="netcdf4")
    assert os.listdir(tmp_path) == []  # neither the target nor a temp file


def test_unwritable_targets_raise_write_error(tmp_path):
    """A missing directory or a failing writer raised a bare OSError (FileNotFoundError, or the
    writer's own), which ``except xtopo.XtopoError`` did not catch."""
    ds = xtopo.datasets.fractal_surface((8, 8), 1.0, hurst=0.8, seed=1)
    target = tmp_path / "missing" / "x.nc"
    with pytest.raises(xtopo.XtopoError, match=f"cannot write {re.escape(str(target))}: No such file") as info:
        xtopo.to_netcdf(ds, target)
    assert isinstance(info.value, OSError) and info.value.errno == errno.ENOENT
    assert str(info.value).startswith("cannot write")
    tree = xtopo.twin({"a": ds})
    with pytest.raises(xtopo.WriteError, match="cannot write"):
        tree.topo.to_netcdf(target)
    assert not (tmp_path / "missing").exists()


def test_an_archive_of_synthetic_data_is_its_own_source(tmp_path):
    """Reading back an xtopo archive of data that came from no file gave no source_file/source_sha256, so
    nothing computed from it said where it came from; an archive of a read file keeps that file's."""
    synthetic = xtopo.datasets.fractal_surface((8, 8), 1.0, hurst=0.8, seed=1)
    path = xtopo.to_netcdf(synthetic, tmp_path / "synthetic.nc")
    back = xtopo.open_topography(path)
    assert back.attrs["source_file"] == "synthetic.nc" and back.attrs["source_format"] == "netcdf"
    assert back.attrs["source_sha256"] == hashlib.sha256((tmp_path / "synthetic.nc").read_bytes()).hexdigest()
    assert back.topo.psd().attrs["source_sha256"] == back.attrs["source_sha256"]
    again = xtopo.open_topography(xtopo.to_netcdf(back, tmp_path / "copy.nc"))  # an archive of a read file
    assert again.attrs["source_file"] == "synthetic.nc"
    assert again.attrs["source_sha256"] == back.attrs["source_sha256"]


def test_read_netcdf_and_open_twin_refuse_what_is_not_a_path():
    # read_netcdf(True) opened file descriptor 1 and closed it (stdout gone for the rest of the process)
    for path in [True, False, 1, 0, None, 2.5]:
        from xtopo.io.netcdf import read_netcdf

        for read in (read_netcdf, xtopo.open_twin):
            with pytest.raises(xtopo.XtopoError, match="path must be a file path"):
                read(path)
        os.fstat(1)  # still open


@pytest.mark.parametrize("name", ["missing.nc", "."])
def test_read_netcdf_of_a_missing_file_or_directory(tmp_path, name):
    # a bare FileNotFoundError / IsADirectoryError from the engine sniffing
    from xtopo.io.netcdf import read_netcdf

    with pytest.raises(xtopo.ReaderError, match="not a readable NetCDF/HDF5 file"):
        read_netcdf(tmp_path / name)


def test_bytes_paths_are_paths(tmp_path):
    # atomic_write raised a bare TypeError ('can only concatenate str (not "bytes") to str')
    ds = xtopo.datasets.fractal_surface((8, 8), 1.0, hurst=0.7, units="um")
    target = os.fsencode(tmp_path / "a.nc")
    assert xtopo.to_netcdf(ds, target) == os.fsdecode(target)
    assert xtopo.io.to_surfacetopography_netcdf(ds, os.fsencode(tmp_path / "st.nc")) == str(tmp_path / "st.nc")
    xr.testing.assert_allclose(xtopo.open_topography(target, units="um").height, ds.height)


@pytest.mark.parametrize("channel", ["abc", True, 2.5, -1, ["height"]])
def test_xtopo_netcdf_has_one_channel(tmp_path, channel):
    # any channel= was ignored and the heights returned
    path = tmp_path / "a.nc"
    xtopo.to_netcdf(xtopo.datasets.fractal_surface((8, 8), 1.0, hurst=0.7, units="um"), path)
    for ok in (None, 0, "height"):
        assert xtopo.open_topography(path, channel=ok).height.shape == (8, 8)
    with pytest.raises(xtopo.UnsupportedFormatError, match="netcdf: (no channel named|channel must be|channel index)"):
        xtopo.open_topography(path, channel=channel)


def test_bad_engine_refused(tmp_path):
    # an array raised numpy's 'truth value ambiguous'; '' was taken as the default
    for engine in [np.array(["netcdf4", "h5netcdf"]), ["netcdf4"], "", 3]:
        ds = xtopo.datasets.fractal_surface((8, 8), 1.0, hurst=0.7, units="um")
        with pytest.raises(xtopo.XtopoError, match="engine must be one of"):
            xtopo.to_netcdf(ds, tmp_path / "a.nc", engine=engine)
