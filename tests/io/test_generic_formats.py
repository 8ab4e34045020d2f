"""Generic formats: text, npy/npz, MATLAB v5/v7.3, HDF5, both NetCDF layouts; size/unit options."""

import re

import numpy as np
import pytest
import xarray as xr

import xtopo
from xtopo.conventions import make_measurement, physical_size, spacing
from xtopo.errors import ReaderError, UnsupportedFormatError, XtopoError
from xtopo.io.registry import detect


@pytest.fixture
def heights():
    rng = np.random.default_rng(0)
    return rng.standard_normal((5, 7))


def _open(path, **kw):
    return xtopo.open_topography(path, units=None, **kw)


def test_text_matrix_without_header_needs_size(tmp_path, heights):
    p = tmp_path / "m.txt"
    np.savetxt(p, heights)
    assert detect(p)[0].name == "text"
    with pytest.raises(ReaderError, match="physical_size") as err:
        _open(p, file_units="um")
    assert str(p) in str(err.value)
    ds = _open(p, physical_size=(1.0, 1.4), file_units="um")
    np.testing.assert_allclose(ds.height.values, heights, rtol=1e-12)
    assert ds.height.attrs["units"] == "um" and spacing(ds, "x") == pytest.approx(0.2)
    assert physical_size(ds, "y") == pytest.approx(1.0)
    nm = _open(p, physical_size=(1.0, 1.4), file_units="um", height_units="nm")
    np.testing.assert_allclose(nm.height.values, heights * 1e-3, rtol=1e-12)


def test_text_header_in_gwyddion_style(tmp_path, heights):
    p = tmp_path / "g.txt"
    p.write_text("# Channel: Height\n# Width: 2.0 mm\n# Height: 500 um\n# Value units: nm\n"
                 + "\n".join("\t".join(f"{v:.17g}" for v in row) for row in heights) + "\n", encoding="utf-8")
    assert detect(p)[0].name == "gwyddion-text"
    ds = _open(p)
    assert ds.height.attrs["units"] == "mm"
    assert physical_size(ds, "x") == pytest.approx(2.0) and physical_size(ds, "y") == pytest.approx(0.5)
    np.testing.assert_allclose(ds.height.values, heights * 1e-6, rtol=1e-12)
    with pytest.raises(ReaderError, match="states its length unit"):
        _open(p, file_units="m")


def test_two_column_text_nonuniform(tmp_path):
    x = np.cumsum(np.random.default_rng(1).uniform(0.5, 1.5, 50))
    h = np.sin(x)
    p = tmp_path / "xy.txt"
    np.savetxt(p, np.column_stack([x, h]))
    ds = _open(p, file_units="um")
    assert ds.attrs["grid"] == "nonuniform"
    np.testing.assert_allclose(ds.x.values, x, rtol=1e-14)
    np.testing.assert_allclose(ds.height.values, h, rtol=1e-14)
    xtopo.conventions.validate(ds)


def test_two_column_text_uniform_within_print_precision(tmp_path):
    x = np.arange(200) * 0.15625
    p = tmp_path / "xy.csv"
    p.write_text("\n".join(f"{a:.1f},{np.cos(a):.5f}" for a in x))  # positions rounded to 0.1
    ds = _open(p, file_units="um")
    assert "grid" not in ds.attrs
    assert spacing(ds) == pytest.approx(0.15625, rel=1e-3)


def test_npy_and_npz(tmp_path, heights):
    np.save(tmp_path / "a.npy", heights)
    np.savez(tmp_path / "b.npz", profile=heights[0], heights=heights)
    a = _open(tmp_path / "a.npy", physical_size=(5.0, 7.0), file_units="nm")
    np.testing.assert_array_equal(a.height.values, heights)
    b = _open(tmp_path / "b.npz", physical_size=(5.0, 7.0), file_units="nm")
    np.testing.assert_array_equal(b.height.values, heights)
    prof = _open(tmp_path / "b.npz", channel="profile", physical_size=7.0, file_units="nm")
    assert prof.height.dims == ("x",)
    assert [c.name for c in xtopo.io.channels(tmp_path / "b.npz")] == ["profile", "heights"]
    with pytest.raises(UnsupportedFormatError, match="nope"):
        _open(tmp_path / "b.npz", channel="nope", physical_size=1.0, file_units="nm")
    with pytest.raises(ReaderError, match="file_units"):
        _open(tmp_path / "a.npy", physical_size=(5.0, 7.0))


def test_npy_never_unpickles(tmp_path):
    np.save(tmp_path / "o.npy", np.array([{"a": 1}, None], dtype=object), allow_pickle=True)
    with pytest.raises(ReaderError, match="no pickles"):
        _open(tmp_path / "o.npy", physical_size=1.0, file_units="m")


def test_npy_header_larger_than_file(tmp_path, heights):
    p = tmp_path / "big.npy"
    np.save(p, heights)
    raw = p.read_bytes()
    assert b"(5, 7)" in raw
    p.write_bytes(raw.replace(b"(5, 7)", b"(9, 9)"))  # same header length, 81 values promised, 35 present
    with pytest.raises(ReaderError):
        _open(p, physical_size=(1.0, 1.0), file_units="m")


def test_matlab_v5(tmp_path, heights):
    scipy_io = pytest.importorskip("scipy.io")
    p = tmp_path / "a.mat"
    scipy_io.savemat(p, {"note": "text", "line": np.arange(4.0), "heights": heights})
    ds = _open(p, physical_size=(1.0, 1.4), file_units="um")
    np.testing.assert_array_equal(ds.height.values, heights)
    assert {c.name for c in xtopo.io.channels(p)} == {"line", "heights"}


def _write_v73(path, arrays):
    h5py = pytest.importorskip("h5py")
    with h5py.File(path, "w", userblock_size=512) as f:
        for name, a in arrays.items():
            f[name] = np.asarray(a).T  # MATLAB stores column-major
            f[name].attrs["MATLAB_class"] = np.bytes_("double")
    with open(path, "r+b") as f:
        f.write(b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: Mon Jan  1 00:00:00 2024 HDF5 schema 1.00 .")


def test_matlab_v73(tmp_path, heights):
    p = tmp_path / "b.mat"
    _write_v73(p, {"heights": heights})
    assert detect(p)[0].name == "matlab"
    ds = _open(p, physical_size=(1.0, 1.4), file_units="um")
    np.testing.assert_array_equal(ds.height.values, heights)


def test_generic_hdf5(tmp_path, heights):
    h5py = pytest.importorskip("h5py")
    p = tmp_path / "a.h5"
    with h5py.File(p, "w") as f:
        f["meta/counts"] = np.arange(3)
        f["scan/topography"] = heights
        f["scan/topography"].attrs["units"] = "nm"
    ds = _open(p, channel="scan/topography", physical_size=(50.0, 70.0))
    assert ds.height.attrs["units"] == "nm"
    np.testing.assert_array_equal(ds.height.values, heights)
    assert [c.name for c in xtopo.io.channels(p)] == ["meta/counts", "scan/topography"]


@pytest.mark.parametrize("units", ["V", "deg", b"nA"])
def test_hdf5_dataset_in_a_unit_that_is_no_length(tmp_path, heights, units):
    """A dataset that states units 'V' (an amplitude or phase channel) was read as heights in file_units,
    its unit ignored without a word; without file_units the error said the file stores no length unit."""
    h5py = pytest.importorskip("h5py")
    p = tmp_path / "amplitude.h5"
    with h5py.File(p, "w") as f:
        f["signal"] = heights
        f["signal"].attrs["units"] = units
    shown = units.decode() if isinstance(units, bytes) else units
    for options in ({}, {"file_units": "um", "physical_size": (1.0, 1.0)}):
        with pytest.raises(ReaderError, match=rf"amplitude.h5.*'signal' states units '{shown}', which is not a length"):
            _open(p, **options)
    # the caller may still say what the values are
    ds = _open(p, file_units="um", height_units="nm", physical_size=(1.0, 1.0))
    np.testing.assert_allclose(ds.height.values, heights * 1e-3)


@pytest.mark.parametrize("size", [(1e-320, 1.0), (1.0, 5e-324)])
def test_physical_size_too_small_for_the_pixels(tmp_path, heights, size):
    """A size whose pixel underflows ended in "coordinate 'y' must be strictly increasing", not naming it."""
    p = tmp_path / "m.npy"
    np.save(p, heights)
    with pytest.raises(ReaderError, match=r"m.npy: physical_size .* is too small for \(5, 7\) pixels"):
        _open(p, physical_size=size, file_units="um")
    assert _open(p, physical_size=(1e-300, 1e-300), file_units="um").height.shape == (5, 7)


def _netcdf3(path, variables, fmt="NETCDF3_64BIT"):
    xr.Dataset(variables, coords={"col": np.arange(variables[next(iter(variables))][1].shape[-1], dtype=float)}
               ).to_netcdf(path, format=fmt, engine="scipy")
    return path


@pytest.mark.parametrize("fmt", ["NETCDF3_CLASSIC", "NETCDF3_64BIT"])
def test_plain_netcdf3_variable(tmp_path, heights, fmt):
    """A NetCDF-3 file in neither xtopo's nor SurfaceTopography's layout was refused by every reader."""
    p = _netcdf3(tmp_path / "plain.nc", {"z": (("row", "col"), heights, {"units": "nm"}),
                                         "other": (("row", "col"), heights * 2, {"units": "nm"})}, fmt)
    ds = _open(p, physical_size=(50.0, 70.0))
    assert ds.attrs["source_format"] == "generic-netcdf" and ds.height.attrs["units"] == "nm"
    np.testing.assert_array_equal(ds.height.values, heights)
    assert (physical_size(ds, "y"), physical_size(ds, "x")) == pytest.approx((50.0, 70.0))
    assert [c.name for c in xtopo.io.channels(p)] == ["z", "other"]  # the coordinate 'col' is an axis
    np.testing.assert_array_equal(_open(p, channel=1, physical_size=(50.0, 70.0)).height.values, heights * 2)
    np.testing.assert_array_equal(_open(p, channel="other", physical_size=(50.0, 70.0)).height.values, heights * 2)
    with pytest.raises(UnsupportedFormatError, match="channel 'col' does not exist"):
        _open(p, channel="col", physical_size=(50.0, 70.0))
    with pytest.raises(ReaderError, match="states its length unit"):
        _open(p, physical_size=(50.0, 70.0), file_units="um")


def test_plain_netcdf3_fill_values_and_units(tmp_path, heights):
    holed = heights.copy()
    holed[1, 2] = -999.0
    p = _netcdf3(tmp_path / "holes.nc", {"heights": (("row", "col"), holed, {"_FillValue": -999.0}),
                                         "amplitude": (("row", "col"), heights, {"units": "V"})})
    ds = _open(p, physical_size=(1.0, 1.0), file_units="um")
    assert ds.height.attrs["units"] == "um" and bool(ds["mask"][1, 2]) and int(ds["mask"].sum()) == 1
    np.testing.assert_array_equal(ds.height.values[~ds["mask"].values], heights[~ds["mask"].values])
    with pytest.raises(ReaderError, match="'amplitude' states units 'V', which is not a length"):
        _open(p, channel="amplitude", physical_size=(1.0, 1.0), file_units="um")
    with pytest.raises(ReaderError, match="stores no length unit"):
        _open(p, physical_size=(1.0, 1.0))


def test_truncated_plain_netcdf3(tmp_path, heights):
    p = _netcdf3(tmp_path / "cut.nc", {"z": (("row", "col"), heights, {"units": "nm"})})
    data = p.read_bytes()
    p.write_bytes(data[: len(data) - 40])
    with pytest.raises(XtopoError, match="cut.nc"):
        _open(p, physical_size=(1.0, 1.0))


def test_xtopo_netcdf_round_trip(tmp_path, heights):
    ds = make_measurement(heights, size=(1.0, 1.4), units="um", periodic=True)
    xtopo.io.to_netcdf(ds, tmp_path / "x.nc")
    back = _open(tmp_path / "x.nc")
    assert back.attrs["source_format"] if "source_format" in back.attrs else "netcdf"
    xr.testing.assert_allclose(back.height, ds.height)


@pytest.mark.parametrize("kind", ["area", "line", "nonuniform", "masked"])
def test_surfacetopography_netcdf_round_trip(tmp_path, heights, kind):
    if kind == "area":
        ds = make_measurement(heights, size=(1.0, 1.4), units="um", periodic=True)
    elif kind == "masked":
        h = heights.copy()
        h[1, 2] = np.nan
        ds = make_measurement(h, size=(1.0, 1.4), units="um")
    elif kind == "line":
        ds = make_measurement(heights[0], size=3.0, units="nm")
    else:
        ds = make_measurement(heights[0], x=np.cumsum(np.arange(1.0, 8.0)), units="mm")
    p = tmp_path / "st.nc"
    xtopo.io.to_surfacetopography_netcdf(ds, p)
    assert detect(p)[0].name == "st-netcdf"
    back = _open(p)
    assert back.attrs["source_format"] == "st-netcdf"
    xr.testing.assert_allclose(back.topo.height, ds.topo.height)
    assert back.attrs["periodic"] == ds.attrs["periodic"]
    with xr.open_dataset(p, engine="scipy") as raw:  # the layout itself: heights(x, y), length/unit attrs
        if kind in ("area", "masked"):
            assert raw.heights.dims == ("x", "y")
            assert float(raw.x.attrs["length"]) == pytest.approx(1.4) and raw.x.attrs["unit"] == "um"
            assert ("mask" in raw) == (kind == "masked")
        elif kind == "nonuniform":
            assert raw.heights.dims == ("n",) and raw.x.dims == ("n",)
    if kind == "nonuniform":  # its positions are stored: a size was silently ignored
        with pytest.raises(ReaderError, match="physical_size"):
            xtopo.open_topography(p, physical_size=2.0)


def test_surfacetopography_reads_our_export(tmp_path, heights):
    st = pytest.importorskip("SurfaceTopography")
    ds = make_measurement(heights, size=(1.0, 1.4), units="um", periodic=True)
    p = tmp_path / "st.nc"
    xtopo.io.to_surfacetopography_netcdf(ds, p)
    reader = st.open_topography(str(p))
    topo = reader.topography()
    np.testing.assert_allclose(topo.heights().T, heights)
    assert tuple(topo.physical_sizes) == pytest.approx((1.4, 1.0))
    assert topo.is_periodic
    reader.close()


def test_surfacetopography_reads_our_export_of_instrument_metadata(tmp_path, heights):
    """The export put xtopo's attrs into ``info`` as they were: SurfaceTopography refused every file with
    an ``instrument`` attr (ValidationError: its InfoModel wants a dict there), i.e. every real file, and a
    tip radius was not where contact.engineering looks for it. Both sides now use ST's structure."""
    st = pytest.importorskip("SurfaceTopography")
    ds = make_measurement(heights[0], size=3.0, units="um", tip_radius=0.5, instrument="Dektak", vendor="Bruker",
                          acquisition_time="2021-02-11T23:39:13", channel="Height")
    p = tmp_path / "st.nc"
    xtopo.io.to_surfacetopography_netcdf(ds, p)
    reader = st.open_topography(str(p))
    topo = reader.topography()
    info = topo.info
    assert info["instrument"]["name"] == "Dektak" and info["instrument"]["vendor"] == "Bruker"
    assert info["instrument"]["parameters"]["tip_radius"] == {"value": 0.5, "unit": "um"}
    assert info["channel_name"] == "Height" and info["acquisition_time"].year == 2021
    # SurfaceTopography's own reliability analysis finds the tip radius
    assert topo.short_reliability_cutoff() == topo.scanning_probe_reliability_cutoff(0.5)
    reader.close()
    back = _open(p)
    for key in ("tip_radius", "tip_radius_units", "instrument", "vendor", "acquisition_time", "channel"):
        assert back.attrs[key] == ds.attrs[key], key
    xr.testing.assert_allclose(back.topo.reliability_cutoff(), ds.topo.reliability_cutoff())


def test_surfacetopography_written_tip_radius_is_read(tmp_path):
    """A tip radius in a file from SurfaceTopography/contact.engineering was left in the attr ``st_info``
    (JSON text): the reliability analysis did not see it."""
    st = pytest.importorskip("SurfaceTopography")
    h = np.random.default_rng(2).standard_normal(64)
    info = {"instrument": {"name": "stylus", "parameters": {"tip_radius": {"value": 2.5, "unit": "µm"}}}}
    st.UniformLineScan(h, 100.0, unit="µm", info=info).to_netcdf(str(tmp_path / "w.nc"))
    ds = _open(tmp_path / "w.nc")
    assert ds.attrs["tip_radius"] == 2.5 and ds.attrs["tip_radius_units"] == "um"
    assert ds.attrs["instrument"] == "stylus"
    assert ds.topo.reliability_cutoff().attrs["method"] == "tip_radius"


def test_read_surfacetopography_written_file(tmp_path):
    st = pytest.importorskip("SurfaceTopography")
    h = np.random.default_rng(2).standard_normal((8, 5))  # ST: first index is x
    st.Topography(h, (2.0, 1.0), unit="nm", periodic=False).to_netcdf(str(tmp_path / "w.nc"))
    ds = _open(tmp_path / "w.nc")
    assert ds.height.dims == ("y", "x") and ds.height.shape == (5, 8)
    np.testing.assert_allclose(ds.height.values, h.T)
    assert physical_size(ds, "x") == pytest.approx(2.0) and ds.height.attrs["units"] == "nm"


def test_size_override_and_refused_units_for_native_formats(tmp_path, heights):
    ds = make_measurement(heights, size=(1.0, 1.4), units="um")
    xtopo.io.to_surfacetopography_netcdf(ds, tmp_path / "st.nc")
    over = _open(tmp_path / "st.nc", physical_size=(2.0, 2.8))
    assert physical_size(over, "x") == pytest.approx(2.8)
    sdf = tmp_path / "a.sdf"
    sdf.write_text("aISO-1.0\nNumPoints = 2\nNumProfiles = 2\nXscale = 1e-6\nYscale = 1e-6\nZscale = 1e-9\n"
                   "DataType = 7\n*\n1 2\n3 BAD\n*\n")
    out = _open(sdf)
    assert bool(out.mask[1, 1]) and float(out.height[0, 1]) == pytest.approx(2e-9)
    over = _open(sdf, physical_size=(4e-6, 8e-6))  # in the file's own unit (m)
    assert physical_size(over, "x") == pytest.approx(8e-6)
    with pytest.raises(XtopoError, match="own units"):
        _open(sdf, height_units="nm")


def test_binary_sdf(tmp_path):
    import struct

    vals = np.array([[1, 2, 3], [4, -(2 ** 15), 6]], dtype="<i2")
    head = (b"bISO-1.0" + b"TEST".ljust(10) + b"0" * 12 + b"0" * 12 + struct.pack("<HH", 3, 2)
            + struct.pack("<dddd", 1e-6, 2e-6, 1e-9, 1e-9) + bytes([0, 5, 0]))
    assert len(head) == 81
    (tmp_path / "b.sdf").write_bytes(head + vals.tobytes())
    ds = _open(tmp_path / "b.sdf")
    assert ds.height.shape == (2, 3) and bool(ds.mask[1, 1])
    assert physical_size(ds, "y") == pytest.approx(4e-6)
    assert float(ds.height[1, 2]) == pytest.approx(6e-9)
    (tmp_path / "t.sdf").write_bytes(head + vals.tobytes()[:-2])
    with pytest.raises(ReaderError, match="t.sdf"):
        _open(tmp_path / "t.sdf")


def test_binary_content_is_not_text(tmp_path):
    p = tmp_path / "noise.txt"
    p.write_bytes(bytes(range(256)) * 20)
    with pytest.raises(UnsupportedFormatError):
        _open(p)


def test_xarray_backend_passes_generic_options(tmp_path, heights):
    np.save(tmp_path / "a.npy", heights)
    ds = xr.open_dataset(tmp_path / "a.npy", engine="xtopo", physical_size=(5.0, 7.0), file_units="nm", units="nm")
    np.testing.assert_array_equal(ds.height.values, heights)
    assert physical_size(ds, "x") == pytest.approx(7.0)


def test_npy_header_with_unbalanced_bracket_and_non_mat_content_name_the_file(tmp_path, heights):
    """The readers themselves raised tokenize.TokenError / scipy's MatReadError (only open_topography's
    catch-all turned them into 'reader failed on malformed content')."""
    from xtopo.io.registry import formats

    p = tmp_path / "h.npy"
    np.save(p, heights)
    raw = p.read_bytes()
    p.write_bytes(raw.replace(b"(5, 7)", b"(5, 7 "))  # a corrupt byte in the header dict
    with pytest.raises(ReaderError, match=r"h.npy: invalid .npy header"):
        formats()["npy"].read(p, physical_size=(1, 1), file_units="m")
    t = tmp_path / "t.mat"
    t.write_text("1 2\n3 4\n")
    with pytest.raises(ReaderError, match=r"t.mat: not a readable MATLAB file"):
        formats()["matlab"].read(t, physical_size=(1, 1), file_units="m")


def test_hdf5_without_heights_is_not_called_corrupt(tmp_path):
    """An HDF5 file with no numeric 1D/2D dataset was reported as 'corrupt HDF5 file: <path>: contains no ...'
    (path twice, an UnsupportedFormatError turned into a corrupt-file ReaderError)."""
    h5py = pytest.importorskip("h5py")
    from xtopo.io.registry import formats

    p = tmp_path / "labels.h5"
    with h5py.File(p, "w") as f:
        f["names"] = np.array([b"a", b"b"])
    with pytest.raises(UnsupportedFormatError) as err:
        formats()["hdf5"].read(p, physical_size=(1, 1), file_units="m")
    assert str(err.value) == f"{p}: contains no 1D or 2D array of heights"
    with pytest.raises(UnsupportedFormatError, match=r"labels.h5: no reader accepts.*hdf5: contains no 1D or 2D"):
        xtopo.open_topography(p)
    # with generic options the NetCDF readers (tried first) refused file_units= instead of saying why
    # the file is not theirs
    with pytest.raises(UnsupportedFormatError, match=r"labels.h5: no reader accepts.*hdf5: contains no 1D or 2D"):
        xtopo.open_topography(p, physical_size=(1, 1), file_units="m")


@pytest.mark.parametrize("path", [None, 5, ["a.txt"]])
def test_a_path_that_is_not_a_path(path):
    for call in (xtopo.io.open_topography, xtopo.io.channels):
        with pytest.raises(ReaderError, match=f"expected a file path .*got {type(path).__name__}"):
            call(path)


def test_open_options_set_the_attrs(tmp_path, heights):
    np.save(tmp_path / "a.npy", heights)
    ds = xtopo.open_topography(tmp_path / "a.npy", physical_size=(5.0, 7.0), file_units="nm", units="um",
                               periodic=False, tip_radius=np.float32(0.5), resolution=2)
    assert ds.attrs["periodic"] == 0 and not xtopo.conventions.is_periodic(ds)
    assert (ds.attrs["tip_radius"], ds.attrs["tip_radius_units"]) == (0.5, "um")
    assert (ds.attrs["resolution"], ds.attrs["resolution_units"]) == (2.0, "um")
    np.testing.assert_allclose(ds.height.values, heights * 1e-3)


@pytest.mark.parametrize("stored, expected", [("true", True), ("FALSE", False), (np.int8(1), True), ("yes", None),
                                              (2, None)])
def test_surfacetopography_periodic_flag_spellings(tmp_path, heights, stored, expected):
    """The reader did bool(int(attr)): the text 'true' raised a bare ValueError, and 2 read as periodic."""
    import netCDF4

    p = tmp_path / "st.nc"
    xtopo.io.to_surfacetopography_netcdf(make_measurement(heights, size=(1.0, 1.4), units="um"), p)
    with netCDF4.Dataset(p, "a") as nc:
        nc["x"].setncattr("periodic", stored)
    if expected is None:
        with pytest.raises(xtopo.ReaderError, match="periodic="):
            _open(p)
    else:
        assert bool(_open(p).attrs["periodic"]) is expected


@pytest.mark.parametrize("info", [-1, "abc", [1, 2], np.zeros(2)])
def test_surfacetopography_export_info_must_be_a_dict(tmp_path, info):
    # any value was JSON-dumped as the file's 'info' (SurfaceTopography reads it as a dict)
    ds = xtopo.datasets.fractal_surface((8, 8), 1.0, hurst=0.7, units="um")
    with pytest.raises(xtopo.ValidationError, match="info must be a dict"):
        xtopo.io.to_surfacetopography_netcdf(ds, tmp_path / "st.nc", info=info)
    assert not (tmp_path / "st.nc").exists()


@pytest.mark.parametrize("path", [1, None, 2.5])
def test_surfacetopography_export_path_must_be_a_path(tmp_path, path):
    # a bare TypeError from os.fspath
    ds = xtopo.datasets.fractal_surface((8, 8), 1.0, hurst=0.7, units="um")
    with pytest.raises(xtopo.XtopoError, match="path must be a file path"):
        xtopo.io.to_surfacetopography_netcdf(ds, path)


def test_surfacetopography_export_refuses_heights_in_another_unit(tmp_path):
    # heights in nm on a µm grid were written with the unit 'nm' for both (the layout has one unit)
    ds = xtopo.datasets.fractal_surface((8, 8), 1.0, hurst=0.7, units="um")
    ds = ds.assign(height=(ds.height * 1000).assign_attrs(units="nm"))
    with pytest.raises(xtopo.UnitsError, match="height in 'nm', coordinate 'y' in 'um'"):
        xtopo.io.to_surfacetopography_netcdf(ds, tmp_path / "st.nc")


@pytest.mark.parametrize("fmt", [["netcdf"], {}, np.array(["netcdf"])])
def test_unhashable_format_refused(tmp_path, fmt):
    # a bare TypeError ('unhashable type') from the format lookup
    path = tmp_path / "a.nc"
    xtopo.to_netcdf(xtopo.datasets.fractal_surface((8, 8), 1.0, hurst=0.7, units="um"), path)
    with pytest.raises(xtopo.UnsupportedFormatError, match="unknown format"):
        xtopo.open_topography(path, format=fmt)


def test_channels_with_a_size_for_maps_beside_a_line(tmp_path, heights):
    """channels() of a container holding a 1D and a 2D array with physical_size=(Ly, Lx) raised a numpy
    broadcast error (wrapped as 'reader failed on malformed content'); the size fits only the map."""
    np.savez(tmp_path / "a.npz", line=heights[0], heights=heights)
    infos = xtopo.io.channels(tmp_path / "a.npz", physical_size=(5.0, 7.0), file_units="um")
    assert [(c.name, c.shape, c.size) for c in infos] == [("line", (7,), None), ("heights", (5, 7), (5.0, 7.0))]
    one = xtopo.io.channels(tmp_path / "a.npz", physical_size=5.0, file_units="um")
    assert [c.size for c in one] == [(5.0,), (5.0, 5.0)]


def test_npy_negative_shape(tmp_path, heights):
    """A negative shape in a .npy header reached file.read (numpy's 'read length must be non-negative')."""
    p = tmp_path / "a.npy"
    np.save(p, heights)
    p.write_bytes(p.read_bytes().replace(b"'shape': (5, 7), ", b"'shape': (-5, 7),"))
    with pytest.raises(ReaderError, match=r"a.npy: invalid shape \(-5, 7\) for the array: negative size") as err:
        _open(p, physical_size=(5.0, 7.0), file_units="um")
    assert "malformed content" not in str(err.value)


@pytest.mark.parametrize("name, write", [
    ("one.txt", lambda p: p.write_text("3.0\n")),
    ("one.npy", lambda p: np.save(p, np.ones((1, 1)))),
    ("one1d.npy", lambda p: np.save(p, np.ones(1))),
])
def test_a_single_value_is_no_measurement(tmp_path, name, write):
    """One height was read as a measurement (a 1x1 map with the given size as its spacing)."""
    write(tmp_path / name)
    with pytest.raises(ReaderError, match=r"at least 2 heights"):
        _open(tmp_path / name, physical_size=5.0, file_units="um")


def test_first_text_row_with_a_bad_number_is_not_a_header(tmp_path):
    """'0x10 1' (a number in a form float() does not read) was silently dropped as a header line."""
    p = tmp_path / "a.txt"
    p.write_text("0x10 1\n2 3\n4 5\n")
    with pytest.raises(ReaderError, match=r"a.txt: the first data row contains a token that is not a number: '0x10'"):
        _open(p, physical_size=(3.0, 2.0), file_units="um")
    p.write_text("2020-01-01 12:00\n2 3\n4 5\n")  # a header line that merely starts with a digit stays a header
    assert _open(p, physical_size=(2.0, 2.0), file_units="um").height.shape == (2, 2)


def test_netcdf4_dimension_scales_are_not_heights(tmp_path, heights):
    """A NetCDF-4 file read as generic HDF5 offered its dimension axes (bare zeros) as channels; by default
    the first one was read as the heights."""
    pytest.importorskip("netCDF4")
    p = tmp_path / "plain.nc"
    xr.Dataset({"topo": (("a", "b"), heights)}).to_netcdf(p, engine="netcdf4")
    assert [c.name for c in xtopo.io.channels(p, file_units="um")] == ["topo"]
    ds = _open(p, physical_size=(5.0, 7.0), file_units="um")
    assert ds.attrs["channel"] == "topo"
    np.testing.assert_array_equal(ds.height.values, heights)


def test_hdf5_heights_in_another_layout_get_the_hdf5_readers_error(tmp_path, heights):
    """An HDF5 file with a dataset 'heights' got the SurfaceTopography reader's "'heights' has dims
    ('phony_dim_0', ...)" for any problem instead of the generic HDF5 reader's."""
    h5py = pytest.importorskip("h5py")
    p = tmp_path / "a.h5"
    with h5py.File(p, "w") as f:
        f["heights"] = heights
        f["heights"].attrs["units"] = "um"
    with pytest.raises(ReaderError, match=r"a.h5: .*stores no physical size; pass physical_size"):
        _open(p)
    np.testing.assert_array_equal(_open(p, physical_size=(5.0, 7.0)).height.values, heights)


@pytest.mark.parametrize("channel", [0.0, False, np.float64(0), 1])
@pytest.mark.parametrize("name", ["a.txt", "a.npy"])
def test_single_channel_readers_take_only_the_index_0(tmp_path, heights, name, channel):
    """channel=0.0 or False was taken as channel 0 by the text and .npy readers (npz/NetCDF refuse them)."""
    p = tmp_path / name
    np.savetxt(p, heights) if name.endswith(".txt") else np.save(p, heights)
    with pytest.raises(UnsupportedFormatError, match=re.escape(f"{name}: has a single channel; channel {channel!r} does not")):
        _open(p, channel=channel, physical_size=(5.0, 7.0), file_units="um")
    assert _open(p, channel=0, physical_size=(5.0, 7.0), file_units="um").height.shape == heights.shape


def test_line_positions_near_the_float_limit_warn_nothing(tmp_path):
    """Positions near 1.7e308 made the grid check's least-squares fit emit numpy overflow RuntimeWarnings."""
    import warnings

    p = tmp_path / "a.txt"
    p.write_text("0 1\n1e308 2\n1.7e308 3\n")
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        ds = _open(p, file_units="um")
    np.testing.assert_array_equal(ds.x.values, [0.0, 1e308, 1.7e308])
    np.testing.assert_array_equal(ds.height.values, [1.0, 2.0, 3.0])


def test_xarray_backend_refuses_drop_variables_that_are_no_names(tmp_path, heights):
    """xr.open_dataset(engine="xtopo", drop_variables=5) silently ignored it (xarray's own engines raise);
    an array of names raised numpy's 'truth value ambiguous'."""
    for drop, match in [(5, "drop_variables must be a variable name or a list of names, got int"),
                                             (object(), "drop_variables must be .* got object"),
                                             ([["mask"]], r"drop_variables item must be a string, got \[.mask.\]"),
                                             (np.array([1, 2]), "drop_variables item must be a string, got np.int64")]:
        np.save(tmp_path / "a.npy", heights)
        with pytest.raises(XtopoError, match=match):
            xr.open_dataset(tmp_path / "a.npy", engine="xtopo", physical_size=(5.0, 7.0), file_units="um",
                            drop_variables=drop)


@pytest.mark.parametrize("drop", ["height", ["height"], np.array(["height", "nothing"]), ()])
def test_xarray_backend_drops_the_variables_named(tmp_path, heights, drop):
    np.save(tmp_path / "a.npy", heights)
    kw = dict(physical_size=(5.0, 7.0), file_units="um")
    ds = xr.open_dataset(tmp_path / "a.npy", engine="xtopo", drop_variables=drop, **kw)
    full = xtopo.open_topography(tmp_path / "a.npy", **kw)
    xr.testing.assert_identical(ds, full.drop_vars(["height"] if len(drop) else []))


@pytest.mark.real_data
@pytest.mark.parametrize("units", ["m", "nm"])
def test_every_reader_gives_spacing_attrs_in_the_unit_of_the_positions(real_data, units):
    """Readers wrote ``x.attrs["spacing"]`` in the file's unit while the positions were converted to
    metres (di-3: 0.039 against 3.9e-8), and a single-pixel axis takes its size from that attribute."""
    from xtopo.conventions import lateral_dims

    checked = 0
    for path in sorted(real_data.iterdir()):
        if path.name == "MANIFEST.md":
            continue
        try:
            ds = xtopo.open_topography(path, units=units)
        except xtopo.XtopoError:
            continue  # files that need options (a unit, a size) are read by their own tests
        for dim in lateral_dims(ds["height"]):
            c = ds[dim]
            assert c.attrs["units"] == units
            if "spacing" in c.attrs and c.size > 1:
                step = (c.values[-1] - c.values[0]) / (c.size - 1)
                np.testing.assert_allclose(c.attrs["spacing"], step, rtol=1e-6, err_msg=f"{path.name} {dim}")
                one = ds.isel({dim: slice(0, 1)})  # a single-pixel axis: its size comes from the attribute
                np.testing.assert_allclose(physical_size(one, dim), step, rtol=1e-6, err_msg=f"{path.name} {dim}")
                checked += 1
    assert checked >= 20
