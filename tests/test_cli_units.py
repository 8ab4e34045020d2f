"""Units and labels people read (issue 26): engineering prefixes on the command line, an aligned contact
table with units, contact results that read back."""

import os
import pathlib
import subprocess
import sys

import pytest

import xtopo
from xtopo._format import format_columns, format_quantities, format_quantity

REPO = pathlib.Path(__file__).resolve().parents[1]
REAL_DATA = REPO.parent / "shared" / "data" / "real"


def _xtopo(*argv, cwd=None):
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    return subprocess.run([sys.executable, "-m", "xtopo", *map(str, argv)], capture_output=True, text=True,
                          env=env, cwd=cwd)


def test_engineering_prefixes():
    assert format_quantity(2.008e-05, "m") == "20.08 µm"
    assert format_quantities([-0.0003526, -0.0002234], "mm") == "-352.6 … -223.4 nm"
    assert format_quantity(5e7, "Pa") == "50 MPa"
    assert format_quantity(0.5945, "Pa m2") == "594.5 mN"  # a load on an area scan, in newtons
    assert format_quantity(0.9999996, "m", digits=3) == "1 m"  # the prefix of the value as printed
    assert format_quantity(0.01, "E*") == "0.01 E*"  # relative units take no prefix


def test_columns_are_aligned_with_units_in_the_header():
    text = format_columns([("mean_pressure", [5e7, 1e8], "Pa"), ("load", [0.59, 1.2], "Pa m2"),
                           ("converged", [True, False], None)])
    lines = text.splitlines()
    assert lines[0].split() == ["mean_pressure", "[MPa]", "load", "[N]", "converged"]
    assert len({len(line) for line in lines}) == 1


def test_info_prints_sizes_and_heights_with_prefixes():
    path = REAL_DATA / "opd-1.opd"
    if not path.is_file():
        pytest.skip("real data not present")
    out = _xtopo("info", path)
    assert out.returncode == 0, out.stderr
    assert "size 94.43 × 125.9 µm" in out.stdout
    assert "heights: -352.6 … -223.4 nm" in out.stdout


def test_contact_command_table_and_file_in_physical_units(tmp_path):
    ds = xtopo.datasets.fractal_surface((32, 32), 1e-5, hurst=0.8, rms_height=1e-8, periodic=False, seed=1)
    src = tmp_path / "s.nc"
    xtopo.to_netcdf(ds, src)
    out = _xtopo("contact", src, "--modulus", "2e9", "--mean-pressures", "1e6", "2e6", "-o", tmp_path / "c.nc")
    assert out.returncode == 0, out.stderr
    table = out.stdout.split("\n\n")[1].splitlines()
    assert table[0].split()[:4] == ["mean_pressure", "[MPa]", "load", "[µN]"]
    assert len({len(line) for line in table}) == 1  # aligned
    res = xtopo.open_contact(tmp_path / "c.nc")
    assert res["area_fraction"].dims == ("mean_pressure",)
    assert res.attrs["modulus_units"] == "Pa" and res["mean_pressure"].attrs["units"] == "Pa"
    assert "pressure" not in res  # scalars by default


def test_contact_results_read_back(tmp_path):
    from xtopo.contact import Scene

    ds = xtopo.datasets.fractal_surface((32, 32), 1e-5, hurst=0.8, rms_height=1e-8, periodic=False, seed=1)
    cur = Scene(ds, modulus=2e9).curve(mean_pressures=[1e6, 2e6])
    xtopo.to_netcdf(cur, tmp_path / "cur.nc")
    back = xtopo.open_contact(tmp_path / "cur.nc")
    xtopo_vars = ["pressure", "area_fraction", "converged", "stiffness"]
    for v in xtopo_vars:
        assert back[v].dims == cur[v].dims and back[v].attrs == cur[v].attrs
    assert back["converged"].dtype == bool
    with pytest.raises(xtopo.ReaderError, match="xtopo.open_contact"):
        xtopo.open_topography(tmp_path / "cur.nc")
    xtopo.to_netcdf(ds, tmp_path / "m.nc")
    with pytest.raises(xtopo.ReaderError, match="open_topography"):
        xtopo.open_contact(tmp_path / "m.nc")


def _two_files(tmp_path):
    paths = []
    for seed in (1, 2):
        ds = xtopo.datasets.fractal_surface((64, 64), 1e-5, hurst=0.8, rms_height=1e-8, periodic=False, seed=seed)
        paths.append(tmp_path / f"s{seed}.nc")
        xtopo.to_netcdf(ds, paths[-1])
    return paths


def test_tip_radius_per_file_on_the_command_line(tmp_path):
    """--tip-radius with units, one per file, reaches the measurements and their reliability cutoff (§4.9)."""
    files = _two_files(tmp_path)
    out = _xtopo("analyze", *files, "--tip-radius", "20nm", "0.03um", "-o", tmp_path / "a.nc")
    assert out.returncode == 0, out.stderr
    rows = [line.split() for line in out.stdout.splitlines() if line.startswith("s1.nc") or line.startswith("s2.nc")]
    assert [r[r.index("nm") - 1] for r in rows] == ["20", "30"]
    import xarray as xr

    with xr.open_datatree(tmp_path / "a.nc") as tree:
        assert tree.to_dataset()["tip_radius"].values.tolist() == pytest.approx([2e-8, 3e-8])
    bad = _xtopo("analyze", *files, "--tip-radius", "1nm", "2nm", "3nm", "-o", tmp_path / "b.nc")
    assert bad.returncode == 2 and "--tip-radius takes one value for every file or one per file" in bad.stderr
    bad = _xtopo("analyze", *files, "--resolution", "20 s", "-o", tmp_path / "b.nc")
    assert bad.returncode == 2 and "--resolution" in bad.stderr


def test_batch_read_options_per_measurement(tmp_path):
    from tests._batch_work import probe_attrs

    files = _two_files(tmp_path)
    res = xtopo.batch.run(probe_attrs, [str(f) for f in files], scheduler="sync", progress=False,
                          read_options={"tip_radius": [2e-8, 3e-8]})
    assert res["tip_radius"].values.tolist() == pytest.approx([2e-8, 3e-8])
    with pytest.raises(xtopo.XtopoError, match="2 measurements"):
        xtopo.batch.run(probe_attrs, [str(f) for f in files], scheduler="sync", progress=False,
                        read_options={"tip_radius": [2e-8]})


def _on_a_terminal(argv, tmp_path):
    """Run the command with stdout and stderr on a pseudo-terminal; returns what it wrote."""
    import pty

    leader, follower = pty.openpty()
    import fcntl
    import struct
    import termios

    fcntl.ioctl(follower, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 120, 0, 0))  # a terminal's size (0×0: no bar)
    env = {**os.environ, "PYTHONPATH": str(REPO), "COLUMNS": "120"}
    proc = subprocess.Popen([sys.executable, "-m", "xtopo", *map(str, argv)], stdout=follower, stderr=follower,
                            env=env, cwd=tmp_path)
    os.close(follower)
    chunks = []
    while True:
        try:
            data = os.read(leader, 65536)
        except OSError:
            break
        if not data:
            break
        chunks.append(data)
    proc.wait()
    os.close(leader)
    return proc.returncode, b"".join(chunks).decode("utf-8", "replace")


def test_progress_on_a_terminal_only(tmp_path):
    files = _two_files(tmp_path)
    rc, text = _on_a_terminal(["analyze", *files, "-o", tmp_path / "a.nc"], tmp_path)
    assert rc == 0, text
    assert "reading files" in text and "twin averages" in text
    rc, text = _on_a_terminal(["analyze", *files, "-q", "-o", tmp_path / "a.nc"], tmp_path)
    assert rc == 0 and "reading files" not in text and "twin averages" not in text
    piped = _xtopo("analyze", *files, "-o", tmp_path / "a.nc")
    assert piped.returncode == 0 and "reading files" not in piped.stderr + piped.stdout
