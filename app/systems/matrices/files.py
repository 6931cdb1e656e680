"""Matrix and vector files of ``system.type: matrices`` read as data: headers first, then the data.

Formats by suffix: Matrix Market (``.mtx``, ``.mm``), NumPy (``.npy``), anything else PETSc
binary. The header of each (the size line of Matrix Market, the ``.npy`` header, the PETSc
class id and sizes) is read and checked before any array is allocated: the rows against
``settings.limits.max_dofs``, the declared entries against the file's size (a header cannot
promise more data than the file holds) and the memory the reading needs against the scene's
memory limit. A 1e12-row header is refused in milliseconds, naming the file and the key.

PETSc binary files are read here with numpy, not by PETSc: PETSc's reader also reads the
``.info`` sidecar next to the file as command-line options (``-mat_view ascii:FILE`` would write
FILE), and a data file must never configure the program. The sidecar is ignored.
"""
from __future__ import annotations

import os
import pathlib
from dataclasses import dataclass

import numpy as np

MM_SUFFIXES = (".mtx", ".mm")
MAT_FILE_CLASSID, VEC_FILE_CLASSID = 1211216, 1211214     # PETSc's binary class ids
BYTES_PER_ENTRY = 64        # a stored entry while reading and checking (COO, CSR, K - K^T, |.|)


class MatrixFileError(ValueError):
    """A file refused for its sizes or layout: ``str(err)`` is one line; ``resource``: a memory limit.
    A file that is not of its format at all raises a plain ValueError ("cannot read ... as ...")."""

    def __init__(self, msg: str, resource: bool = False):
        super().__init__(msg)
        self.resource = resource


@dataclass(frozen=True)
class Header:
    """What a matrix file's header says: rows, columns, number of stored values (rows x cols for a
    dense file) and whether it is dense."""

    rows: int
    cols: int
    entries: int            # values stored (a dense file: rows x cols)
    dense: bool


def kind_of(path: pathlib.Path) -> str:
    """The format of a matrix file by its suffix: ``Matrix Market`` (``.mtx``, ``.mm``), ``NumPy
    .npy``, else ``PETSc binary``."""
    suffix = path.suffix.lower()
    return "Matrix Market" if suffix in MM_SUFFIXES else "NumPy .npy" if suffix == ".npy" else "PETSc binary"


def _mm_header(path: pathlib.Path) -> Header:
    import scipy.io
    try:
        rows, cols, entries, fmt, field, symmetry = scipy.io.mminfo(str(path))
    except Exception as err:        # noqa: BLE001 - the user's file
        raise ValueError(f"not a Matrix Market file ({' '.join(str(err).split())[:100]})") from None
    if field == "complex":
        raise MatrixFileError("complex entries; a real matrix is needed")
    stored = entries * (2 if symmetry != "general" and fmt == "coordinate" else 1)
    return Header(int(rows), int(cols), int(stored), fmt == "array")


def _npy_header(path: pathlib.Path) -> Header:
    with open(path, "rb") as f:
        try:
            version = np.lib.format.read_magic(f)
            shape, _, dtype = (np.lib.format.read_array_header_1_0(f) if version == (1, 0)
                               else np.lib.format.read_array_header_2_0(f))
        except Exception as err:    # noqa: BLE001
            raise ValueError(f"not a NumPy .npy file ({' '.join(str(err).split())[:100]})") from None
    if dtype.hasobject or dtype.kind not in "biuf":
        raise MatrixFileError(f"entries of type {dtype}: real numbers are needed")
    if len(shape) not in (1, 2):
        raise MatrixFileError(f"an array of {len(shape)} dimensions {tuple(shape)}: a matrix has 2, a vector 1")
    rows = int(shape[0])
    cols = int(shape[1]) if len(shape) == 2 else 1
    return Header(rows, cols, rows * cols, True)


def _petsc_layout(path: pathlib.Path, kind: str) -> tuple[np.dtype, list[int], int]:
    """(integer type, header values, header bytes) of a PETSc binary file (32- or 64-bit indices)."""
    classid = MAT_FILE_CLASSID if kind == "matrix" else VEC_FILE_CLASSID
    count = 4 if kind == "matrix" else 2
    with open(path, "rb") as f:
        head = f.read(8 * count)
    for itype in (np.dtype(">i4"), np.dtype(">i8")):
        size = itype.itemsize * count
        if len(head) >= size:
            values = [int(v) for v in np.frombuffer(head[:size], dtype=itype)]
            if values[0] == classid:
                return itype, values, size
    other = "a vector" if kind == "matrix" else "a matrix"
    raise ValueError(f"not a PETSc binary {kind} file (no {kind} class id at its start; {other}, or "
                          "another format? Matrix Market needs the suffix .mtx or .mm, NumPy .npy)")


def _petsc_header(path: pathlib.Path, kind: str) -> Header:
    itype, values, hsize = _petsc_layout(path, kind)
    if kind == "vector":
        n = values[1]
        if n < 0:
            raise MatrixFileError(f"the header declares {n} entries")
        return Header(n, 1, n, True)
    _, rows, cols, nnz = values
    if rows < 0 or cols < 0 or nnz < 0:
        raise MatrixFileError(f"the header declares {rows} x {cols} with {nnz} nonzeros (dense PETSc binary "
                              "matrices are not supported)")
    return Header(rows, cols, nnz, False)


def header(path: pathlib.Path, kind: str) -> Header:
    """The sizes a file declares (``kind``: "matrix" or "vector"); raises :class:`MatrixFileError`."""
    suffix = path.suffix.lower()
    if suffix in MM_SUFFIXES:
        return _mm_header(path)
    if suffix == ".npy":
        return _npy_header(path)
    return _petsc_header(path, kind)


def check_header(h: Header, path: pathlib.Path, max_dofs: int, memory_bytes: float, how: str) -> None:
    """The declared sizes against the file's size and the limits (before anything is allocated)."""
    size = os.path.getsize(path)
    if h.rows > max_dofs:
        raise MatrixFileError(f"{path.name} declares {h.rows} rows, above settings.limits.max_dofs = {max_dofs}; "
                              "raise the limit for a system this large")
    # every stored value takes at least 2 bytes of Matrix Market text ("1\n", or "1 2\n" for two mirrored
    # values), 1 byte of .npy and 8 bytes of PETSc binary
    suffix = path.suffix.lower()
    least = 2 if suffix in MM_SUFFIXES else 1 if suffix == ".npy" else 8
    if h.entries * least > size + 1024:
        raise MatrixFileError(f"{path.name} declares {h.rows} x {h.cols} with {h.entries} stored values, more than "
                              f"its {size} bytes can hold: the header is wrong or the file is cut off")
    need = h.entries * (8 * 4 if h.dense else BYTES_PER_ENTRY) + 8 * 8 * (h.rows + 1)
    if need > memory_bytes:
        raise MatrixFileError(f"{path.name} ({h.rows} x {h.cols}, {h.entries} stored values) needs about "
                              f"{need / 2**30:.3g} GiB to read, above {how}", resource=True)


def read_petsc(path: pathlib.Path, kind: str):
    """A PETSc binary matrix (scipy CSR) or vector (ndarray) read with numpy (no ``.info``, no PETSc)."""
    import scipy.sparse as sp
    itype, values, hsize = _petsc_layout(path, kind)
    size = os.path.getsize(path)
    real = np.dtype(">f8")
    with open(path, "rb") as f:
        f.seek(hsize)
        if kind == "vector":
            n = values[1]
            if size - hsize < 8 * n:
                raise MatrixFileError(f"{path.name} is cut off or complex: {size} bytes for {n} real values")
            return np.fromfile(f, dtype=real, count=n).astype(float)
        _, rows, cols, nnz = values
        expected = hsize + itype.itemsize * (rows + nnz) + real.itemsize * nnz
        if size < expected:
            raise MatrixFileError(f"{path.name} is cut off or complex: {size} bytes, {expected} expected for "
                                  f"{rows} x {cols} with {nnz} real nonzeros")
        lengths = np.fromfile(f, dtype=itype, count=rows).astype(np.int64)
        indices = np.fromfile(f, dtype=itype, count=nnz).astype(np.int64)
        data = np.fromfile(f, dtype=real, count=nnz).astype(float)
    if np.any(lengths < 0) or int(lengths.sum()) != nnz:
        raise MatrixFileError(f"{path.name}: row lengths that do not add up to the {nnz} nonzeros of its header")
    if nnz and (indices.min() < 0 or indices.max() >= cols):
        raise MatrixFileError(f"{path.name}: column indices outside 0 ... {cols - 1}")
    indptr = np.concatenate([[0], np.cumsum(lengths)])
    return sp.csr_matrix((data, indices, indptr), shape=(rows, cols))
