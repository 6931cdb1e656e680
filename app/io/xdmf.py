"""The ParaView time series of the states (``paraview/states.xdmf`` and its ``.h5`` parts)."""
from __future__ import annotations

import pathlib

import numpy as np


class XdmfSeries:
    """meshio's XDMF time series whose HDF5 data are built in memory and written to disk by Python.

    HDF5 does not survive a full disk: after a failed write its object destructors raise inside
    h5py and the process then dies of a segmentation fault (HDF5 1.10, h5py 3.7), so a user would
    see a crash instead of "no space left". Here HDF5 only ever writes into a ``BytesIO``; each
    finished image goes to disk through ``open``/``write``, where a full disk is a plain
    ``OSError(ENOSPC)``. Memory stays bounded: a new ``.h5`` part is started once a part holds
    ``part_bytes`` of data (``states.h5`` holds the mesh and the first states, ``states.1.h5`` ...
    the next; the ``.xdmf`` names the part of each array). Parts are written with ``"xb"``: the
    series never overwrites a file (the folder is the study's own staging folder).
    """

    def __init__(self, path: pathlib.Path, part_bytes: int = 64 * 2**20):
        import h5py
        import meshio

        series = self

        class Writer(meshio.xdmf.TimeSeriesWriter):
            def __enter__(self):
                series._open_part()
                return self

            def __exit__(self, *exc):
                if exc and exc[0] is not None:      # the study failed: nothing more is written
                    series._discard_part()
                    return False
                series._close_part()
                import xml.etree.ElementTree as ET
                with open(self.filename, "xb") as f:
                    ET.ElementTree(self.xdmf_file).write(f)
                return False

            def write_data(self, t, point_data=None, cell_data=None):
                super().write_data(t, point_data=point_data, cell_data=cell_data)
                if series._held >= series.part_bytes:
                    series._close_part()
                    series._open_part()

            def numpy_to_xml_string(self, data):
                series._held += np.asarray(data).nbytes
                return super().numpy_to_xml_string(data)

        self._h5py = h5py
        self.path = pathlib.Path(path)
        self.part_bytes = int(part_bytes)
        self.parts: list[pathlib.Path] = []
        self._buf = None
        self._held = 0
        self.writer = Writer(self.path)

    def _open_part(self) -> None:
        import io
        k = len(self.parts)
        name = self.path.with_suffix(".h5") if k == 0 else self.path.with_suffix(f".{k}.h5")
        self.parts.append(name)
        self._buf = io.BytesIO()
        self.writer.h5_filename = str(name)
        self.writer.h5_file = self._h5py.File(self._buf, "w")
        self._held = 0

    def _close_part(self) -> None:
        self.writer.h5_file.close()
        image = self._buf.getvalue()
        self._buf = None
        with open(self.parts[-1], "xb") as f:
            f.write(image)

    def _discard_part(self) -> None:
        if self._buf is not None:
            self.writer.h5_file.close()
            self._buf = None

    def __enter__(self):
        return self.writer.__enter__()

    def __exit__(self, *exc):
        return self.writer.__exit__(*exc)
