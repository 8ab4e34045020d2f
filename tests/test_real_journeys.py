"""Journeys on the real instrument files in ../shared/data/real: read, preprocess, analyse, archive.

Each test skips when the directory is absent (see the ``real_data`` fixture).
"""

import numpy as np
import pytest
import xarray as xr

import xtopo


def test_fill_missing_fills_a_real_map_read_as_a_transposed_view(real_data):
    """opd-1.opd is stored column by column; the reader's map is a transposed view of the file.

    fill_missing left its 116 undefined pixels NaN and dropped the mask (the fill was written
    into a copy), so every analysis after it failed or ran on NaN.
    """
    ds = xtopo.open_topography(real_data / "opd-1.opd")
    assert int(ds["mask"].sum()) > 0
    filled = ds.topo.fill_missing()
    assert np.isfinite(filled.height).all()
    xr.testing.assert_equal(filled["filled"], ds["mask"].rename("filled").assign_attrs(filled["filled"].attrs))
    # the measured pixels are untouched
    keep = ~ds["mask"].values
    np.testing.assert_array_equal(filled.height.values[keep], ds.height.values[keep])


@pytest.mark.parametrize("name", ["di-5.di", "dektak-1.csv", "opd-1.opd"])
def test_surfacetopography_reads_the_export_of_a_real_file(real_data, tmp_path, name):
    """Exports of real files (all have an ``instrument``) were refused by SurfaceTopography 1.27."""
    st = pytest.importorskip("SurfaceTopography")
    ds = xtopo.open_topography(real_data / name)
    path = tmp_path / "st.nc"
    ds.topo.to_surfacetopography_netcdf(path)
    reader = st.open_topography(str(path))
    topo = reader.topography()
    heights = np.ma.filled(topo.heights().astype(float), np.nan)
    np.testing.assert_array_equal(heights.T if heights.ndim == 2 else heights, ds.height.values)
    assert topo.info["instrument"]["name"] == ds.attrs["instrument"]
    if "tip_radius" in ds.attrs:  # the same tip criterion on both sides (ST: along x only, xtopo: x and y)
        assert topo.info["instrument"]["parameters"]["tip_radius"]["value"] == ds.attrs["tip_radius"]
        assert topo.short_reliability_cutoff() > 0
    reader.close()


@pytest.mark.parametrize("name", ["di-1.di", "old_bruker.002", "mi-1.mi", "nid-1.nid", "spot_1-1000nm.ibw",
                                  "example_ps.tiff", "sample_0.jpk-qi-image", "top-1.top", "stp-1.stp"])
def test_afm_maps_have_one_orientation(real_data, name):
    """The AFM readers keep the file's rows, the bottom line of the image first: their maps are those of
    SurfaceTopography (whose ``heights().T`` is Gwyddion's view, top line first) upside down. The WSxM
    reader was in addition mirrored in x (WSxM stores each row right to left)."""
    st = pytest.importorskip("SurfaceTopography")
    reader = st.open_topography(str(real_data / name))
    topo = reader.topography()
    gwyddion_view = np.asarray(topo.heights(), dtype=float).T
    heights = xtopo.open_topography(real_data / name, units=topo.unit.replace("µ", "u")).height.values
    np.testing.assert_allclose(heights, gwyddion_view[::-1], rtol=1e-12, atol=1e-12 * np.ptp(gwyddion_view))
    reader.close()


def test_twin_of_real_files_of_several_instruments(real_data, tmp_path):
    """A twin from files of an AFM (nm), a stylus profiler (line scan, um) and an optical profiler (mm,
    undefined pixels): nodes are named after the files (the OPD and OPDx readers title both 'Raw', so the
    nodes were 'Raw' and 'Raw_2'), the archive round trip is identical, the averages carry provenance."""
    files = ["di-3.di", "opdx-3.opdx", "opd-1.opd"]
    tree = xtopo.twin([real_data / f for f in files], name="mixed")
    assert set(tree.children) == {"di-3", "opdx-3", "opd-1"}
    path = tmp_path / "twin.nc"
    tree.topo.to_netcdf(path)
    back = xtopo.open_twin(path)
    for node in tree.children:
        xr.testing.assert_identical(back[node].to_dataset().compute(), tree[node].to_dataset())
    psd = back.topo.psd()
    assert sorted(str(s) for s in psd["source_file"].values) == sorted(files)
    assert psd["average"].attrs["units"] == "m3" and int(psd["count"].max()) >= 1


@pytest.mark.parametrize("name", ["di-5.di", "frt-2.frt", "dektak-1.csv", "KautschukInfiniteFocus.x3p"])
def test_preprocess_analyse_archive_reopen(real_data, tmp_path, name):
    """Detrend and fill a real file, archive it, reopen: the same data, attributes and history, and the
    same analyses (with the same provenance)."""
    from xtopo.io.netcdf import PROVENANCE_KEYS

    raw = xtopo.open_topography(real_data / name)
    prep = raw.topo.detrend("plane").topo.fill_missing()
    path = tmp_path / "prep.nc"
    xtopo.to_netcdf(prep, path)
    back = xtopo.open_topography(path)
    xr.testing.assert_identical(back.drop_attrs(deep=False).assign_attrs(
        {k: v for k, v in back.attrs.items() if k not in PROVENANCE_KEYS or k == "Conventions"}), prep)
    assert back.attrs["source_sha256"] == raw.attrs["source_sha256"]
    for analysis in ("psd", "acf", "vbm", "sdrp"):
        a, b = getattr(prep.topo, analysis)(), getattr(back.topo, analysis)()
        xr.testing.assert_identical(a, b)


@pytest.mark.parametrize("name,crop", [("di-3.di", {"y": slice(0, 64), "x": slice(0, 64)}),
                                       ("dektak-1.csv", {"x": slice(0, 1024)})])
def test_contact_on_real_scans(real_data, name, crop):
    """Free-boundary contact of a real area and line scan: the load is the sum of the pressures, and the
    penetration found for a mean pressure gives that mean pressure back."""
    from xtopo.contact.scene import Scene

    ds = xtopo.open_topography(real_data / name).isel(crop).topo.detrend()
    scene = Scene(ds, modulus=1.0, modulus_units="GPa")
    res = scene.solve(mean_pressure=0.01)
    assert bool(res.converged) and res.attrs["boundary"] == "free"
    cell = np.prod([float(ds[d][1] - ds[d][0]) for d in ("y", "x") if d in ds.dims])
    np.testing.assert_allclose(float(res["pressure"].sum()) * cell, float(res["load"]), rtol=1e-10)
    again = scene.solve(penetration=float(res.penetration))
    np.testing.assert_allclose(float(again.mean_pressure), 0.01, rtol=1e-3)
    assert 0 < float(res.area_fraction) < 1
