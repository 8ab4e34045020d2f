import numpy as np
import pytest
import xarray as xr

import xtopo

from xtopo.datasets import example_twin, fractal_surface


@pytest.mark.parametrize("engine", ["netcdf4", "h5netcdf"])
def test_archive_round_trip_is_identical(tmp_path, engine):
    tree = example_twin()
    path = tmp_path / "twin.nc"
    tree.topo.to_netcdf(path, engine=engine)
    back = xtopo.open_twin(path)
    assert set(back.children) == set(tree.children)
    for name in tree.children:
        xr.testing.assert_identical(back[name].to_dataset(), tree[name].to_dataset())
    assert back.attrs["title"] == tree.attrs["title"]
    assert back.attrs["Conventions"] == "CF-1.12, ACDD-1.3"
    assert back.attrs["xtopo_version"] == xtopo.__version__


def test_twin_from_datasets_and_files(tmp_path):
    a = fractal_surface((32, 32), 1e-6, hurst=0.7, seed=1)
    b = fractal_surface(256, 1e-4, hurst=0.7, seed=2, units="um")
    path = tmp_path / "b.nc"
    xtopo.to_netcdf(b, path)
    tree = xtopo.twin({"afm": a, "profile": path}, name="steel", material="AISI 52100")
    assert tree.attrs["title"] == "steel" and tree.attrs["material"] == "AISI 52100"
    assert set(tree.children) == {"afm", "profile"}
    # files written by xtopo are opened lazily
    import dask.array as dsa

    assert isinstance(tree["profile"].dataset["height"].data, dsa.Array)
    np.testing.assert_array_equal(tree["profile"].dataset["height"].values, b.height.values)
    # names from titles; duplicates get a suffix
    t2 = xtopo.twin([a, a])
    assert len(t2.children) == 2
    with pytest.raises(xtopo.XtopoError):
        xtopo.twin([])


@pytest.mark.parametrize("engine", ["netcdf4", "h5netcdf"])
def test_twin_of_files_holds_what_read_netcdf_reads(tmp_path, engine):
    """A twin of xtopo NetCDF files reads their coordinates and attributes with h5py (xarray's open cost 14 ms a
    file) and their data when computed: each measurement equals read_netcdf's, dtypes and attr types included
    (a map with a mask, a line scan); a file xarray decodes further (integers with a fill value) is opened by xarray."""
    from xtopo.io.netcdf import read_netcdf

    hole = np.zeros((24, 16), bool)
    hole[2:4, 3:5] = True
    area = fractal_surface((24, 16), (1.5e-6, 1e-6), hurst=0.7, seed=1, periodic=False).assign(mask=(("y", "x"), hole))
    area.attrs.update(tip_radius=1e-8, tip_radius_units="m", notes=np.array([1.0, 2.0]))
    line = fractal_surface(64, 1e-4, hurst=0.7, seed=2, units="um")
    scaled = fractal_surface(32, 1e-4, hurst=0.7, seed=3)
    scaled["height"].encoding.update(scale_factor=1e-9, dtype="int32", _FillValue=-1)
    paths = [xtopo.to_netcdf(ds, tmp_path / f"{n}.nc", engine=engine)
             for n, ds in (("area", area), ("line", line), ("scaled", scaled))]
    tree = xtopo.twin(paths)
    for path, name in zip(paths, ("area", "line", "scaled")):
        lazy, want = tree[name].to_dataset(), read_netcdf(path)
        assert {v: lazy[v].dtype for v in lazy.variables} == {v: want[v].dtype for v in want.variables}
        got = lazy.compute()
        xr.testing.assert_identical(got, want)
        for a, b in [(got.attrs, want.attrs)] + [(got[v].attrs, want[v].attrs) for v in want.variables]:
            assert {k: type(v) for k, v in a.items()} == {k: type(v) for k, v in b.items()}
    assert tree["area"].dataset["mask"].chunks is not None


def test_archive_checksums_listed(tmp_path):
    a = fractal_surface((16, 16), 1.0, hurst=0.5)
    a.attrs["source_sha256"] = "ab" * 32
    tree = xtopo.twin({"a": a})
    tree.topo.to_netcdf(tmp_path / "t.nc")
    back = xtopo.open_twin(tmp_path / "t.nc")
    assert "a: " + "ab" * 32 in back.attrs["source_checksums"]
    tree.topo.to_netcdf(tmp_path / "u.nc", checksums=False)
    assert "source_sha256" not in xtopo.open_twin(tmp_path / "u.nc")["a"].attrs


def test_open_twin_on_garbage_names_file(tmp_path):
    p = tmp_path / "junk.nc"
    p.write_bytes(b"not netcdf at all")
    with pytest.raises(xtopo.ReaderError, match="junk.nc"):
        xtopo.open_twin(p)


@pytest.fixture(scope="module")
def small_twin():
    return xtopo.twin({"a": fractal_surface((32, 32), 1.0, hurst=0.8, seed=1, units="um"),
                       "b": fractal_surface(64, 0.5, hurst=0.8, seed=2, units="um")})


@pytest.mark.parametrize("measurements", [None, 5, "scan.nc", [None], {"a": 3}])
def test_twin_of_non_measurements_refused(measurements):
    with pytest.raises(xtopo.ValidationError, match="must be"):
        xtopo.twin(measurements)


def test_twin_average_of_a_dataset_refused():
    from xtopo.stitching import twin_psd

    with pytest.raises(xtopo.ValidationError, match="expected a twin"):
        twin_psd(fractal_surface((16, 16), 1.0, hurst=0.8))  # was AttributeError: no 'children'


def test_a_measurement_too_small_for_a_curve_adds_nothing_to_the_average():
    """A 2×2 map has no SDRP distances: its curve is all NaN (it crashed the interpolation) and the average
    equals that of the other measurements."""
    big = fractal_surface((64, 64), 1.0, hurst=0.8, seed=1, units="um")
    tiny = fractal_surface((2, 2), 0.1, hurst=0.8, seed=2, units="um")
    both = xtopo.twin({"big": big, "tiny": tiny}).topo.sdrp()
    alone = xtopo.twin({"big": big}).topo.sdrp()
    assert bool(both.curves.sel(measurement="tiny").isnull().all())
    xr.testing.assert_allclose(both.average, alone.average)


def test_twin_from_any_mapping():
    # a mapping that is not a dict was iterated like a list: its keys were opened as file paths
    import types

    a = fractal_surface((8, 8), 1.0, hurst=0.8, seed=1, units="um")
    tree = xtopo.twin(types.MappingProxyType({"afm": a}))
    assert list(tree.children) == ["afm"]
    xr.testing.assert_identical(tree["afm"].to_dataset(), a)


@pytest.mark.parametrize("paths", [("/afm/s1", "/afm/s2", "/stylus"), ("/", "/stylus")])
def test_measurements_below_the_children_refused(tmp_path, paths):
    # nested measurements were skipped without a word: averages used only /stylus, and the
    # archive written by to_netcdf lost /afm/s1 and /afm/s2
    a = fractal_surface((16, 16), 1.0, hurst=0.8, seed=1, units="um")
    tree = xr.DataTree.from_dict({p: a for p in paths})
    with pytest.raises(xtopo.ValidationError, match="children of the root"):
        xtopo.twins.measurements(tree)
    with pytest.raises(xtopo.ValidationError, match="children of the root"):
        tree.topo.psd()
    with pytest.raises(xtopo.ValidationError, match="children of the root"):
        tree.topo.to_netcdf(tmp_path / "t.nc")


def test_archive_keeps_groups_that_are_not_measurements(tmp_path):
    # to_netcdf wrote only the measurements: a /notes group vanished from the archive
    a = fractal_surface((8, 8), 1.0, hurst=0.8, seed=1, units="um")
    notes = xr.Dataset({"load": ("step", [1.0, 2.0], {"units": "N", "long_name": "applied load"})},
                       attrs={"comment": "indentation log"})
    tree = xtopo.twin({"a": a}).assign({"notes": xr.DataTree(notes)})
    tree.topo.to_netcdf(tmp_path / "t.nc")
    back = xtopo.open_twin(tmp_path / "t.nc")
    assert set(back.children) == {"a", "notes"}
    xr.testing.assert_identical(back["notes"].to_dataset(), notes)
    xr.testing.assert_identical(back["a"].to_dataset(), a)


def test_archive_of_a_dataset_refused(tmp_path):
    # was AttributeError: 'Dataset' object has no attribute 'to_dataset'
    with pytest.raises(xtopo.ValidationError, match="expected a twin"):
        xtopo.twins.to_netcdf(fractal_surface((8, 8), 1.0, hurst=0.8), tmp_path / "t.nc")


def test_archive_checksums_listed_afresh(tmp_path):
    # the root's source_checksums of a restored archive were written again with checksums=False
    # (and after its measurement was removed); checksums='no' counted as True
    a = fractal_surface((8, 8), 1.0, hurst=0.5, seed=1).assign_attrs(source_sha256="ab" * 32)
    b = fractal_surface((8, 8), 1.0, hurst=0.5, seed=2)
    xtopo.twin({"a": a, "b": b}).topo.to_netcdf(tmp_path / "t.nc")
    back = xtopo.open_twin(tmp_path / "t.nc")
    assert back.attrs["source_checksums"] == "a: " + "ab" * 32
    back.topo.to_netcdf(tmp_path / "u.nc", checksums=False)
    assert "source_checksums" not in xtopo.open_twin(tmp_path / "u.nc").attrs
    back.drop_nodes("a").topo.to_netcdf(tmp_path / "v.nc")
    assert "source_checksums" not in xtopo.open_twin(tmp_path / "v.nc").attrs


@pytest.mark.parametrize("analysis", ["psd", "acf", "vbm", "sdrp"])
def test_a_single_point_measurement_adds_nothing_to_the_average(analysis):
    # twin_psd/acf/sdrp raised a bare ValueError (min of an empty array) for a 1-point line scan
    big = fractal_surface((32, 32), 1.0, hurst=0.8, seed=1, units="um")
    point = xtopo.make_measurement(np.array([1.0]), spacing=1.0, units="um")
    both = getattr(xtopo.twin({"big": big, "point": point}).topo, analysis)()
    alone = getattr(xtopo.twin({"big": big}).topo, analysis)()
    assert int(both.curves.sel(measurement="point").count()) == 0
    xr.testing.assert_allclose(both.average, alone.average)
    if analysis != "vbm":  # a single point has no slope, no spectrum, no height difference
        with pytest.raises(xtopo.XtopoError, match="nothing to average|at least two points"):
            getattr(xtopo.twin({"point": point}).topo, analysis)()


def test_summary_counts_nan_heights_as_missing():
    # a measurement with NaN heights but no 'mask' variable was reported 0 % missing
    from xtopo.summary import summary_table

    a = fractal_surface((8, 8), 1.0, hurst=0.8, seed=1, units="um")
    a["height"][:2, :] = np.nan  # a quarter, no mask
    masked = xtopo.make_measurement(a.height.values, spacing=1 / 8, units="um")  # the same with a mask
    table = summary_table({"nan": a, "masked": masked})
    expected = xr.DataArray([25.0, 25.0], dims="measurement", coords={"measurement": ["nan", "masked"]})
    xr.testing.assert_allclose(table.missing_percent, expected)


@pytest.mark.parametrize("engine", ["netcdf4", "h5netcdf"])
def test_names_in_any_script_survive_the_archive(tmp_path, engine):
    """Node names kept only ASCII letters: "Stahl ü Probe" became "Stahl___Probe" and "钢" became
    "unnamed" (two such names: "unnamed", "unnamed_2"). A decomposed "ü" (u + combining diaeresis)
    is stored in NFC, so it is normalised before it becomes a node name."""
    ds = fractal_surface((8, 8), 1.0, hurst=0.8, seed=2)
    names = {"Stahl ü Probe": "Stahl_ü_Probe", "钢": "钢", "Stahl u\u0308": "Stahl_ü", "a/b": "a_b"}
    tree = xtopo.twin({key: ds for key in names})
    assert list(tree.children) == list(names.values())
    tree.topo.to_netcdf(tmp_path / "t.nc", engine=engine)
    back = xtopo.open_twin(tmp_path / "t.nc")
    assert list(back.children) == list(names.values())
    xr.testing.assert_allclose(back["钢"].to_dataset().height, ds.height)


def test_summary_table_takes_a_list_one_measurement_or_a_twin():
    # a list raised AttributeError ('list' object has no attribute 'items'), a Dataset KeyError 'height'
    # (a Dataset is a Mapping of its variables), a DataTree AttributeError
    from xtopo.summary import format_table, summary_table

    a = fractal_surface((8, 8), 1.0, hurst=0.8, seed=1, units="um").assign_attrs(title="afm")
    b = fractal_surface(16, 1.0, hurst=0.8, seed=2, units="um").assign_attrs(title="afm")  # same title: deduplicated
    c = fractal_surface(16, 1.0, hurst=0.8, seed=3, units="um")
    c.attrs = {}  # no name: measurement_<index>
    by_dict = summary_table({"afm": a, "afm_2": b, "measurement_2": c})
    for given in ([a, b, c], (a, b, c)):
        xr.testing.assert_identical(summary_table(given), by_dict)
    xr.testing.assert_identical(summary_table(a), by_dict.isel(measurement=[0]))
    xr.testing.assert_identical(summary_table(xtopo.twin({"afm": a})), by_dict.isel(measurement=[0]))
    xr.testing.assert_identical(summary_table({"afm": xtopo.conventions.height_of(a)}),
                                by_dict.isel(measurement=[0]))  # a height DataArray
    assert "afm_2" in format_table(summary_table([a, b]))


@pytest.mark.parametrize("bad", [3, "a.nc", {"a": 3}, [xr.Dataset()], {"a": xr.Dataset({"h": ("x", [1.0])})}])
def test_summary_table_refuses_what_is_no_measurement(bad):
    from xtopo.summary import summary_table

    with pytest.raises(xtopo.ValidationError, match="measurement"):
        summary_table(bad)


def test_summary_table_refuses_a_batch_and_prints_metres():
    from xtopo.summary import format_table, summary_table

    a = fractal_surface((8, 8), 1.0, hurst=0.8, seed=1, units="um")
    with pytest.raises(xtopo.GridError, match="extra dims"):  # was TypeError from float() of an array
        summary_table({"batch": xr.concat([a, a], dim="sample")})
    line = fractal_surface(16, 1.0, hurst=0.8, seed=2, rms_height=1.0, units="m")
    assert "1e+03 mm" not in format_table(summary_table({"l": line}))  # 1 m (and Rq 0.99999...) print as 1 m


@pytest.mark.parametrize("table", [None, "table", xr.Dataset(), np.zeros(3)])
def test_format_table_needs_a_summary_table(table):
    # a bare AttributeError ('NoneType' object has no attribute 'sizes') or KeyError 'measurement'
    from xtopo.summary import format_table

    with pytest.raises(xtopo.ValidationError, match="expected a table made by summary_table"):
        format_table(table)
