"""contact.engineering containers (ZIP + index.json/meta.yml): in as twins, out for SurfaceTopography.

SurfaceTopography (the peer that defines the format) writes and reads the containers side by side.
"""

from __future__ import annotations

import json
import os
import shutil
import warnings
import zipfile

import numpy as np
import pytest
import xarray as xr

import xtopo
from xtopo.conventions import lateral_dims, length_factor, physical_size
from xtopo.errors import ReaderError, ValidationError, XtopoError
from tests.io.test_x3p_security import _patch_declared_size

ST = pytest.importorskip("SurfaceTopography")
from SurfaceTopography import NonuniformLineScan, Topography, UniformLineScan  # noqa: E402
from SurfaceTopography.Container.IO import read_container, write_containers  # noqa: E402
from SurfaceTopography.Container.SurfaceContainer import InMemorySurfaceContainer  # noqa: E402


def _zip(path, members: dict):
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as zf:
        for name, data in members.items():
            if isinstance(data, (str, os.PathLike)) and os.path.isfile(data):
                zf.write(data, name)
            else:
                zf.writestr(zipfile.ZipInfo(name), data)
    return path


def _st_heights_m(t) -> np.ndarray:
    """A SurfaceTopography topography's heights in m, xtopo's order ((y, x) for maps), NaN where undefined."""
    h = np.ma.filled(np.ma.asarray(t.heights(), dtype=float), np.nan) * length_factor(t.unit, "m")
    return h.T if h.ndim == 2 else h


def _xtopo_m(ds) -> np.ndarray:
    return ds.height.values * length_factor(ds.height.attrs["units"], "m")


def _sizes_m(ds) -> list:
    f = length_factor(ds.height.attrs["units"], "m")
    return [physical_size(ds, d) * f for d in lateral_dims(ds.height)][::-1]  # [Lx, Ly] as SurfaceTopography


def _st_surfaces(seed=0):
    """An AFM-like map (tip radius), a stylus profile (uniform line scan) and a TEM contour (nonuniform)."""
    rng = np.random.default_rng(seed)
    afm = xtopo.datasets.fractal_surface((32, 48), (2.0, 3.0), hurst=0.8, rms_height=0.05, periodic=False,
                                         seed=seed)
    t_afm = Topography(afm.height.values.T.copy(), (3.0, 2.0), unit="um", periodic=False,
                       info={"name": "afm", "instrument": {"name": "AFM", "parameters": {
                           "tip_radius": {"value": 20.0, "unit": "nm"}}}})
    prof = xtopo.datasets.fractal_surface(400, 2.0, hurst=0.8, rms_height=1e-3, periodic=False, seed=seed + 1)
    t_sty = UniformLineScan(prof.height.values.copy(), 2.0, unit="mm", periodic=False,
                            info={"name": "stylus", "instrument": {"name": "Dektak", "parameters": {
                                "tip_radius": {"value": 2.5, "unit": "um"}}}})
    x = np.sort(rng.uniform(0, 200.0, 60))
    t_tem = NonuniformLineScan(x, np.sin(x / 7.0) * 3 + rng.normal(0, 0.3, x.size), unit="nm",
                               info={"name": "tem"})
    return [t_afm, t_sty, t_tem]


def test_container_written_by_surfacetopography_opens_as_twin(tmp_path):
    topos = _st_surfaces()
    path = tmp_path / "st.zip"
    write_containers([InMemorySurfaceContainer(topos)], str(path))
    tree = xtopo.open_twin(path)
    assert isinstance(tree, xr.DataTree) and list(tree.children) == ["afm", "stylus", "tem"]
    for t, (name, node) in zip(topos, tree.children.items()):
        ds = node.to_dataset()
        np.testing.assert_allclose(_xtopo_m(ds), _st_heights_m(t), rtol=1e-12, atol=0)
        if name != "tem":
            np.testing.assert_allclose(_sizes_m(ds), np.asarray(t.physical_sizes) * length_factor(t.unit, "m"))
        assert ds.attrs["container_datafile"] == "squeezed-netcdf"
        assert "squeezed NetCDF read as stored" in ds.attrs["history"]
    afm, tem = tree["afm"].to_dataset(), tree["tem"].to_dataset()
    assert afm.attrs["instrument"] == "AFM"
    assert afm.attrs["tip_radius"] * length_factor(afm.attrs["tip_radius_units"], "nm") == pytest.approx(20.0)
    assert tem.attrs["grid"] == "nonuniform"
    np.testing.assert_allclose(tem.x.values * length_factor(tem.x.attrs["units"], "nm"), topos[2].positions())
    assert tree.attrs["source_container"] == "st.zip" and tree.attrs["title"] == "surface0"


@pytest.mark.parametrize("drop", ["meta.yml", "index.json"])
def test_either_metadata_file_is_enough(tmp_path, drop):
    """The newer layout (index.json) alone, or an older download's meta.yml alone."""
    src = tmp_path / "st.zip"
    write_containers([InMemorySurfaceContainer(_st_surfaces(1)[:2])], str(src))
    with zipfile.ZipFile(src) as zf:
        members = {n: zf.read(n) for n in zf.namelist() if n != drop}
    tree = xtopo.open_twin(_zip(tmp_path / "one.zip", members))
    assert list(tree.children) == ["afm", "stylus"]
    assert tree["stylus"].attrs["instrument"] == "Dektak"


def _ce_layout(tmp_path, real_data) -> tuple:
    """The CE layout of an older contact.engineering download, built from real files: original files,
    meta.yml with !!python/tuple sizes, height scale, filling, detrending and instrument parameters."""
    rng = np.random.default_rng(3)
    x = np.sort(rng.uniform(0, 250.0, 80))
    tem = tmp_path / "tem.asc"
    np.savetxt(tem, np.column_stack([x, 5 * np.sin(x / 11.0) + 0.02 * x + rng.normal(0, 0.4, x.size)]))
    meta = f"""\
creation_time: '2021-06-21 15:06:49.300694+00:00'
surfaces:
- category: exp
  description: "three instruments, one film"
  name: film
  creator:
    name: A. Tester
  topographies:
  - creator: {{name: A. Tester, orcid: 0000-0000-0000-0000}}
    data_source: 0
    datafile: {{original: 00-tem.asc}}
    detrend_mode: height
    height_scale: 1.0
    is_periodic: false
    measurement_date: 2016-02-15
    name: tem.asc
    size: !!python/tuple
    - {x[-1] - x[0]}
    unit: nm
    instrument: {{name: TEM, type: microscope-based, parameters: {{resolution: {{value: 0.5, unit: nm}}}}}}
  - data_source: 0
    datafile: {{original: 01-afm.di}}
    detrend_mode: height
    height_scale: 0.5
    is_periodic: false
    name: afm.di
    size: !!python/tuple [10.0, 10.0]
    unit: µm
    instrument: {{name: Dimension Icon, type: contact-based, parameters: {{tip_radius: {{value: 10, unit: nm}}}}}}
  - data_source: 0
    datafile: {{original: 02-optical.opd}}
    detrend_mode: curvature
    fill_undefined_data_mode: harmonic
    is_periodic: false
    name: optical.opd
    unit: mm
  - data_source: 0
    datafile: {{original: 03-stylus.csv}}
    detrend_mode: curvature
    height_scale: 1.0
    is_periodic: false
    name: stylus.csv
    description: Dektak stylus profile
    size: !!python/tuple [1.5]
    unit: mm
    instrument: {{name: Dektak, type: contact-based, parameters: {{tip_radius: {{value: 2.5, unit: µm}}}}}}
versions:
  topobank: 0.13.0
"""
    path = _zip(tmp_path / "download.zip", {"meta.yml": meta.encode(), "00-tem.asc": str(tem),
                                            "01-afm.di": str(real_data / "di-3.di"),
                                            "02-optical.opd": str(real_data / "opd-1.opd"),
                                            "03-stylus.csv": str(real_data / "dektak-1.csv")})
    return path


@pytest.mark.real_data
def test_ce_download_with_original_files_matches_surfacetopography(tmp_path, real_data):
    path = _ce_layout(tmp_path, real_data)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # SurfaceTopography warns about its own deprecations
        container, = read_container(str(path))
        st = [container[i] for i in range(len(container))]
    tree = xtopo.open_twin(path)
    assert list(tree.children) == ["tem", "afm", "optical", "stylus"]
    assert tree.attrs["title"] == "film" and tree.attrs["category"] == "exp"
    assert tree.attrs["creator_name"] == "A. Tester"
    for t, (name, node) in zip(st, tree.children.items()):
        ds = node.to_dataset()
        h, h_st = _xtopo_m(ds), _st_heights_m(t)
        assert h.shape == h_st.shape, name
        # the same detrended heights: rms and the distribution (orientation conventions of the readers aside)
        if name == "tem":
            # xtopo fits the tilt at the points of a nonuniform scan, SurfaceTopography to the piecewise-linear
            # profile: a few per cent apart on a sparse contour
            assert np.std(h) == pytest.approx(np.std(h_st), rel=0.05)
        else:
            # the harmonic fills differ in detail; SurfaceTopography's curvature fit of a uniform line scan is
            # not the least-squares fit at the points that xtopo's is (0.5 % apart on this profile)
            rtol = {"optical": 1e-3, "stylus": 1e-2}.get(name, 1e-9)
            np.testing.assert_allclose(np.sort(h.ravel()), np.sort(h_st.ravel()), rtol=0, atol=3 * rtol * np.std(h_st))
            assert np.std(h) == pytest.approx(np.std(h_st), rel=rtol), name
        if name != "tem":  # the Dektak readers differ by 1.3e-4 on the profile's length
            np.testing.assert_allclose(_sizes_m(ds), np.asarray(t.physical_sizes) * length_factor(t.unit, "m"),
                                       rtol=1e-3)
        assert ds.attrs["container_datafile"] == "original"
    hist = {n: tree[n].attrs["history"] for n in tree.children}
    assert "file_units='nm'" in hist["tem"] and "detrend(mode='plane'" in hist["tem"]
    assert "height_scale=0.5" in hist["afm"]
    assert "fill_missing(harmonic)" in hist["optical"] and "detrend(mode='curvature'" in hist["optical"]
    afm, stylus = tree["afm"].to_dataset(), tree["stylus"].to_dataset()
    assert afm.attrs["tip_radius"] * length_factor(afm.attrs["tip_radius_units"], "nm") == pytest.approx(10)
    assert stylus.attrs["tip_radius"] * length_factor(stylus.attrs["tip_radius_units"], "um") == pytest.approx(2.5)
    assert stylus.attrs["description"] == "Dektak stylus profile"
    assert tree["tem"].attrs["acquisition_time"] == "2016-02-15"
    assert tree["tem"].attrs["creator_orcid"] == "0000-0000-0000-0000"
    assert not np.isnan(tree["optical"].height.values).any()


def _small_twin(seed=0):
    area = xtopo.datasets.fractal_surface((24, 32), (1e-6, 1.5e-6), hurst=0.8, rms_height=1e-8, periodic=True,
                                          seed=seed)
    h = area.height.values.copy()
    h[3:5, 7:9] = np.nan  # missing data travel as SurfaceTopography's mask
    area = area.assign(height=area.height.copy(data=h)).assign_attrs(tip_radius=2e-8, tip_radius_units="m",
                                                                     instrument="AFM", description="an AFM map")
    line = xtopo.datasets.fractal_surface(300, 3e-3, hurst=0.7, rms_height=1e-6, periodic=False, seed=seed + 1)
    line = line.assign_attrs(resolution=1e-5, resolution_units="m", acquisition_time="2024-05-06T07:08:09",
                         measurement_kind="profiles")
    x = np.cumsum(np.random.default_rng(seed).uniform(1e-9, 3e-9, 50))
    tem = xtopo.make_measurement(np.sin(x / 2e-8) * 1e-9, x=x, units="m")
    return xtopo.twin({"afm": area, "stylus": line, "tem": tem}, name="sample A", description="round trip")


def test_to_container_round_trip_through_surfacetopography(tmp_path):
    tree = _small_twin()
    path = xtopo.to_container(tree, tmp_path / "out.zip")
    with zipfile.ZipFile(path) as zf:
        assert "meta.yml" in zf.namelist() and "index.json" not in zf.namelist()  # a nonuniform scan: no index.json
    container, = read_container(str(path))
    assert len(container) == 3
    for t, (name, node) in zip([container[i] for i in range(3)], tree.children.items()):
        ds = node.to_dataset()
        assert t.unit == ds.height.attrs["units"]
        np.testing.assert_array_equal(_st_heights_m(t), _xtopo_m(ds))  # NaN where masked, on both sides
        if name != "tem":
            np.testing.assert_allclose(t.physical_sizes, _sizes_m(ds), rtol=1e-14)
            assert t.is_periodic == bool(ds.attrs["periodic"])
        else:
            np.testing.assert_allclose(t.positions(), ds.x.values, rtol=1e-14)
    assert container[0].info["instrument"]["parameters"]["tip_radius"] == {"value": 2e-8, "unit": "m"}
    back = xtopo.open_twin(path)
    assert back.attrs["title"] == "sample A" and list(back.children) == list(tree.children)
    for name in tree.children:
        a, b = tree[name].to_dataset(), back[name].to_dataset()
        np.testing.assert_array_equal(a.height.values, b.height.values)
        np.testing.assert_array_equal(a.x.values, b.x.values)
        for key in ("tip_radius", "resolution", "periodic", "grid", "measurement_kind"):
            assert a.attrs.get(key) == b.attrs.get(key), (name, key)
    assert back["stylus"].attrs["acquisition_time"] == "2024-05-06T07:08:09"
    assert back["afm"].attrs["description"] == "an AFM map"


def test_tags_survive_a_read_and_write(tmp_path):
    """Tags of a surface and of a measurement are written back as contact.engineering reads them (a list)."""
    tree = _small_twin()
    tree.attrs["tags"] = json.dumps(["steel", "polished"])
    tree["afm"].attrs["tags"] = "blasted"  # a plain text: one tag
    back = xtopo.open_twin(xtopo.to_container(tree, tmp_path / "tags.zip"))
    assert json.loads(back.attrs["tags"]) == ["steel", "polished"]
    assert json.loads(back["afm"].attrs["tags"]) == ["blasted"]
    again = xtopo.open_twin(xtopo.to_container(back, tmp_path / "again.zip"))
    assert again.attrs["tags"] == back.attrs["tags"] and again["afm"].attrs["tags"] == back["afm"].attrs["tags"]


def test_to_container_without_nonuniform_scans_writes_index_json(tmp_path):
    tree = _small_twin()
    tree = xtopo.twin({"afm": tree["afm"].to_dataset(), "stylus": tree["stylus"].to_dataset()}, name="s")
    path = xtopo.to_container(tree, tmp_path / "out.zip")
    with zipfile.ZipFile(path) as zf:
        index = json.loads(zf.read("index.json"))
    from SurfaceTopography.Container.IO.Schema import ContainerMeta

    ContainerMeta.model_validate(index)  # the schema SurfaceTopography and contact.engineering validate
    assert index["surfaces"][0]["topographies"][1]["measurement_date"] == "2024-05-06"
    container, = read_container(str(path))  # read through index.json
    np.testing.assert_array_equal(_st_heights_m(container[1]), tree["stylus"].height.values)


def test_several_surfaces_are_several_twins(tmp_path):
    a, b = _small_twin(0), _small_twin(1)
    path = xtopo.to_container({"first": a, "second": b}, tmp_path / "two.zip")
    twins = xtopo.io.open_container(path)
    assert list(twins) == ["first", "second"]
    np.testing.assert_array_equal(twins["second"]["afm"].height.values, b["afm"].height.values)
    with pytest.raises(ValidationError, match="surface="):
        xtopo.open_twin(path)
    np.testing.assert_array_equal(xtopo.open_twin(path, surface="second")["stylus"].height.values,
                                  b["stylus"].height.values)
    assert xtopo.open_twin(path, surface=0).attrs["title"] == "first"
    with pytest.raises(ValidationError, match="'first', 'second'"):
        xtopo.open_twin(path, surface="third")
    assert len(read_container(str(path))) == 2


def test_surface_option_on_a_netcdf_twin_is_refused(tmp_path):
    path = xtopo.twins.to_netcdf(_small_twin(), tmp_path / "t.nc")
    with pytest.raises(ValidationError, match="surface="):
        xtopo.open_twin(path, surface=0)


def test_to_container_is_atomic(tmp_path, monkeypatch):
    target = tmp_path / "keep.zip"
    target.write_bytes(b"old")
    with pytest.raises(XtopoError):
        xtopo.to_container({"s": "not a twin"}, target)

    def full_disk(*args, **kwargs):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(zipfile.ZipFile, "writestr", full_disk)
    with pytest.raises(xtopo.WriteError, match="keep.zip"):
        xtopo.to_container(_small_twin(), target)
    assert target.read_bytes() == b"old" and os.listdir(tmp_path) == ["keep.zip"]


# --- hostile containers -------------------------------------------------------------------------

def _one(name="m.csv", extra="", datafile=None):
    datafile = datafile or f"{{original: {name}}}"
    return f"surfaces:\n- name: s\n  topographies:\n  - name: m\n    datafile: {datafile}\n    unit: um\n{extra}"


def _line_csv():
    x = np.arange(20) * 0.1
    return "\n".join(f"{a} {b}" for a, b in zip(x, np.sin(x))).encode()


def test_minimal_yaml_container_reads(tmp_path):
    path = _zip(tmp_path / "ok.zip", {"meta.yml": _one(), "m.csv": _line_csv()})
    ds = xtopo.open_twin(path)["m"].to_dataset()
    assert ds.height.attrs["units"] == "m" and ds.sizes["x"] == 20


@pytest.mark.parametrize("meta, match", [
    (b"surfaces: [unclosed", "YAML"),
    (b"!!python/object/apply:os.system ['echo owned > owned.txt']", "YAML"),
    (b"surfaces:\n- !!python/object/new:builtins.dict {}\n", "YAML"),
    (b"a: &a [1, 1, 1, 1, 1, 1, 1, 1, 1, 1]\nb: &b [*a, *a, *a, *a, *a, *a, *a, *a, *a, *a]\n"
     b"c: &c [*b, *b, *b, *b, *b, *b, *b, *b, *b, *b]\nd: &d [*c, *c, *c, *c, *c, *c, *c, *c, *c, *c]\n"
     b"e: &e [*d, *d, *d, *d, *d, *d, *d, *d, *d, *d]\nf: &f [*e, *e, *e, *e, *e, *e, *e, *e, *e, *e]\n"
     b"g: [*f, *f, *f, *f, *f, *f, *f, *f, *f, *f]\n", "alias bomb"),
    (b"- just a list", "surfaces"),
    (b"surfaces:\n- name: s\n  topographies:\n  - name: m\n", "datafile"),
    (b"\xff\xfe not text", "UTF-8"),
])
def test_hostile_metadata_is_refused(tmp_path, monkeypatch, meta, match):
    monkeypatch.chdir(tmp_path)
    path = _zip(tmp_path / "bad.zip", {"meta.yml": meta, "m.csv": _line_csv()})
    with pytest.raises(ReaderError, match=match) as info:
        xtopo.open_twin(path)
    assert "bad.zip" in str(info.value)
    assert not (tmp_path / "owned.txt").exists()


def test_bad_index_json_is_refused(tmp_path):
    path = _zip(tmp_path / "bad.zip", {"index.json": b"{not json", "m.csv": _line_csv()})
    with pytest.raises(ReaderError, match="JSON"):
        xtopo.open_twin(path)


def test_missing_member_is_named(tmp_path):
    path = _zip(tmp_path / "gone.zip", {"meta.yml": _one("absent.csv")})
    with pytest.raises(ReaderError, match="'absent.csv'.*not in the archive"):
        xtopo.open_twin(path)


@pytest.mark.parametrize("member", ["../evil.csv", "/etc/passwd", "a/../../evil.csv"])
def test_traversal_names_are_refused(tmp_path, member):
    path = _zip(tmp_path / "trav.zip", {"meta.yml": _one(member), "m.csv": _line_csv()})
    with pytest.raises(ReaderError, match="path traversal"):
        xtopo.open_twin(path)
    path = _zip(tmp_path / "trav2.zip", {"meta.yml": _one(), "m.csv": _line_csv(), member: b"x"})
    with pytest.raises(ReaderError, match="path traversal"):
        xtopo.open_twin(path)
    assert not (tmp_path.parent / "evil.csv").exists()


def test_huge_declared_size_is_refused_before_extraction(tmp_path):
    path = _zip(tmp_path / "bomb.zip", {"meta.yml": _one(), "m.csv": _line_csv()})
    _patch_declared_size(path, "m.csv", 3 << 30)
    with pytest.raises(ReaderError, match="zip bomb"):
        xtopo.open_twin(path)
    path = _zip(tmp_path / "bomb2.zip", {"meta.yml": _one(), "m.csv": _line_csv()})
    _patch_declared_size(path, "meta.yml", 1 << 25)
    with pytest.raises(ReaderError, match="zip bomb|more than"):
        xtopo.open_twin(path)


def test_member_that_decompresses_to_more_than_declared_is_refused(tmp_path):
    path = _zip(tmp_path / "lie.zip", {"meta.yml": _one(), "m.csv": _line_csv()})
    _patch_declared_size(path, "m.csv", 10)
    with pytest.raises(ReaderError, match="m.csv"):
        xtopo.open_twin(path)


def test_bad_values_name_the_topography(tmp_path):
    for extra, match in (("    size: [-1]\n", "'size'"), ("    height_scale: .nan\n", "height_scale"),
                         ("    unit: parsec-ish\n", "unit")):
        meta = _one(extra=extra).replace("    unit: um\n", "") if "unit:" in extra else _one(extra=extra)
        path = _zip(tmp_path / "v.zip", {"meta.yml": meta, "m.csv": _line_csv()})
        with pytest.raises(ReaderError, match=match) as info:
            xtopo.open_twin(path)
        assert "topography 0 ('m')" in str(info.value)


def test_unsupported_detrend_mode_uses_the_squeezed_file_or_is_refused(tmp_path):
    tree = xtopo.twin({"m": xtopo.open_twin(_zip(tmp_path / "ok.zip", {"meta.yml": _one(),
                                                                      "m.csv": _line_csv()}))["m"].to_dataset()})
    squeezed = tmp_path / "sq"
    xtopo.to_container(tree, squeezed)
    with zipfile.ZipFile(squeezed) as zf:
        nc = zf.read("m-squeezed.nc")
    meta = _one(extra="    detrend_mode: mad-tilt\n", datafile="{original: m.csv, squeezed-netcdf: m.nc}")
    ds = xtopo.open_twin(_zip(tmp_path / "both.zip", {"meta.yml": meta, "m.csv": _line_csv(), "m.nc": nc}))["m"]
    assert ds.attrs["container_datafile"] == "squeezed-netcdf" and "'mad-tilt'" in ds.attrs["history"]
    meta = _one(extra="    detrend_mode: mad-tilt\n")
    with pytest.raises(ReaderError, match="mad-tilt"):
        xtopo.open_twin(_zip(tmp_path / "orig.zip", {"meta.yml": meta, "m.csv": _line_csv()}))


def test_size_that_contradicts_the_file_warns_and_keeps_the_file(tmp_path):
    tree = _small_twin()
    src = xtopo.to_container(xtopo.twin({"a": tree["afm"].to_dataset()}), tmp_path / "a.zip")
    with zipfile.ZipFile(src) as zf:
        nc = zf.read("a-squeezed.nc")
    meta = _one(datafile="{squeezed-netcdf: a.nc}", extra="    size: [1.0, 1.0]\n")
    with pytest.warns(UserWarning, match="differs"):
        ds = xtopo.open_twin(_zip(tmp_path / "w.zip", {"meta.yml": meta, "a.nc": nc}))["m"]
    np.testing.assert_allclose(_sizes_m(ds.to_dataset()), _sizes_m(tree["afm"].to_dataset()))


def test_not_a_container_zip_is_not_taken_for_one(tmp_path):
    path = _zip(tmp_path / "other.zip", {"readme.txt": b"hello"})
    with pytest.raises(ReaderError):
        xtopo.open_twin(path)
    with pytest.raises(ReaderError, match="neither index.json nor meta.yml"):
        xtopo.io.open_container(path)
    (tmp_path / "junk.zip").write_bytes(b"PK\x03\x04 not really")
    with pytest.raises(ReaderError, match="junk.zip"):
        xtopo.io.open_container(tmp_path / "junk.zip")


def test_real_download_layout_from_the_surfacetopography_repository(tmp_path):
    """container-2.zip of SurfaceTopography's tests (a contact.engineering download: TEM contour, AFM
    map, stylus profile) when a copy is at hand (XTOPO_CE_CONTAINER); not shipped with xtopo."""
    src = os.environ.get("XTOPO_CE_CONTAINER")
    if not src or not os.path.isfile(src):
        pytest.skip("set XTOPO_CE_CONTAINER to a contact.engineering download to run")
    path = shutil.copy(src, tmp_path / "download.zip")
    tree = xtopo.open_twin(path)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        container, = read_container(str(path))
    for i, (name, node) in enumerate(tree.children.items()):
        assert np.std(_xtopo_m(node.to_dataset())) == pytest.approx(np.std(_st_heights_m(container[i])), rel=5e-3)
