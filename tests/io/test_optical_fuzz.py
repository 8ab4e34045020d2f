"""Fast fuzz smoke test of the optical-format readers (the full harness lives elsewhere).

Each real file is truncated at 10 points and corrupted at 20 random places; every
read must end quickly with a valid Dataset or an XtopoError naming the file.
"""

from __future__ import annotations


import numpy as np
import pytest
import xarray as xr

from xtopo.conventions import validate
from xtopo.errors import XtopoError
from xtopo.io.registry import formats

pytestmark = pytest.mark.real_data

FILES = {"opd-1.opd": "opd", "opdx-3.opdx": "opdx", "x3p-2.x3p": "x3p", "ISO5436-sample4_bin.x3p": "x3p",
         "sample-land.x3p": "x3p", "sur-3.sur": "sur", "mnt-1.mnt": "mnt", "plu-1.plu": "plu",
         "metropro-1.dat": "metropro", "al3d-1.al3d": "al3d", "frt-2.frt": "frt", "tmd-1.tmd": "tmd",
         "nms-1.nms": "nms", "bcrf-1.bcrf": "bcr"}


def _variants(raw: bytes, rng):
    n = len(raw)
    for frac in np.linspace(0, 0.999, 10):
        yield raw[:int(frac * n)]
    for _ in range(20):
        buf = bytearray(raw)
        # header-heavy corruption: half of the hits land in the first 4 kB where the size fields live
        pos = int(rng.integers(0, min(n, 4096))) if rng.random() < 0.5 else int(rng.integers(0, n))
        width = int(rng.integers(1, 9))
        buf[pos:pos + width] = rng.integers(0, 256, size=len(buf[pos:pos + width]), dtype=np.uint8).tobytes()
        yield bytes(buf)


@pytest.mark.parametrize("name", sorted(FILES))
def test_truncated_and_corrupted_files_fail_cleanly(real_data, tmp_path, name):
    fmt = formats()[FILES[name]]
    raw = (real_data / name).read_bytes()
    rng = np.random.default_rng(sum(raw[:64]) + len(raw))
    for i, data in enumerate(_variants(raw, rng)):
        path = tmp_path / f"v{i}_{name}"
        path.write_bytes(data)
        try:
            ds = fmt.read(path)
        except XtopoError as exc:
            assert path.name in str(exc), f"error does not name the file: {exc}"
        else:
            assert isinstance(ds, xr.Dataset)
            validate(ds)
        path.unlink()
