"""The ParaView time series: HDF5 writes only into memory, the disk sees plain Python writes.

HDF5 1.10 (through h5py 3.7) crashes the process with a segmentation fault after a write fails on a
full disk; these tests check that a full disk is an ``OSError(ENOSPC)`` instead, and that a series
split into several ``.h5`` parts reads back the same in meshio and in VTK's XDMF reader (ParaView's).
"""
from __future__ import annotations

import errno

import numpy as np
import pytest
from conftest import fill_disk, tmpfs

from app.io.xdmf import XdmfSeries


def _write(path, steps, rng, part_bytes=64 * 2**20):
    pts = rng.random((50, 2))
    cells = rng.integers(0, 50, (80, 3))
    data = [(rng.random((50, 3)), rng.random(80)) for _ in range(steps)]
    series = XdmfSeries(path, part_bytes=part_bytes)
    with series as w:
        w.write_points_cells(pts, [("triangle", cells)])
        for k, (u, vm) in enumerate(data):
            w.write_data(k, point_data={"u": u}, cell_data={"vm": [vm]})
    return series, pts, cells, data


@pytest.mark.parametrize("part_bytes", [64 * 2**20, 3000])
def test_series_reads_back(tmp_path, part_bytes):
    import meshio
    import pyvista as pv
    series, pts, cells, data = _write(tmp_path / "states.xdmf", 7, np.random.default_rng(1), part_bytes)
    names = sorted(p.name for p in tmp_path.glob("*.h5"))
    assert names == sorted(p.name for p in series.parts)
    assert (len(names) == 1) == (part_bytes > 10**6)
    r = meshio.xdmf.TimeSeriesReader(tmp_path / "states.xdmf")
    p, c = r.read_points_cells()
    assert np.array_equal(p[:, :2], pts) and np.array_equal(c[0].data, cells)
    assert r.num_steps == len(data)
    for k, (u, vm) in enumerate(data):
        t, pd, cd = r.read_data(k)
        assert t == k and np.array_equal(pd["u"], u) and np.array_equal(cd["vm"][0], vm)
    reader = pv.get_reader(str(tmp_path / "states.xdmf"))
    assert len(reader.time_values) == len(data)
    reader.set_active_time_value(reader.time_values[-1])
    block = next(b for b in reader.read() if b is not None and "u" in b.point_data)
    assert np.allclose(block.point_data["u"], data[-1][0])


def test_series_refuses_to_overwrite(tmp_path):
    (tmp_path / "states.h5").write_bytes(b"user's")
    with pytest.raises(FileExistsError):
        _write(tmp_path / "states.xdmf", 2, np.random.default_rng(2))
    assert (tmp_path / "states.h5").read_bytes() == b"user's"
    assert not (tmp_path / "states.xdmf").exists()


def test_full_disk_is_an_oserror_not_a_crash(tmp_path):
    """Deterministic form of the full-tmpfs run test: the disk is full before the series is written."""
    with tmpfs(tmp_path / "mnt", "1m") as mnt:
        fill_disk(mnt)
        with pytest.raises(OSError) as err:
            _write(mnt / "states.xdmf", 40, np.random.default_rng(3))
        assert err.value.errno == errno.ENOSPC
