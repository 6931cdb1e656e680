"""Matrix files are data (issue 19): PETSc's ``.info`` sidecar is ignored, headers are checked
before allocation, meaningless systems are refused at any size.
"""
from __future__ import annotations

import struct
import time

import numpy as np
import pytest
import scipy.io
import scipy.sparse as sp
import yaml
from conftest import one_error_line, run_cli, run_cli_here


def _chain(n: int, held: bool = True) -> sp.csr_matrix:
    """Stiffness of a chain of unit springs on n DOFs: held at both ends (SPD) or free (singular)."""
    e = np.ones(n)
    A = sp.diags([-e[:-1], 2 * e, -e[:-1]], [-1, 0, 1]).tolil()
    if not held:
        A[0, 0] = A[n - 1, n - 1] = 1.0
    return A.tocsr()


def _petsc_write(path, A) -> None:
    from petsc4py import PETSc
    A = sp.csr_matrix(A)
    mat = PETSc.Mat().createAIJ(A.shape, csr=(A.indptr.astype(PETSc.IntType), A.indices.astype(PETSc.IntType),
                                              A.data), comm=PETSc.COMM_SELF)
    v = PETSc.Viewer().createBinary(str(path), mode="w", comm=PETSc.COMM_SELF)
    mat.view(v)
    v.destroy()
    mat.destroy()


def _scene(tmp_path, K: str, M: str | None = None, analyses=("mceip_mu",), limits=None) -> str:
    system = {"type": "matrices", "K": K, "contact": [[0, 1, 1]], "state": {"reactions": [[0.1, -1.0]]}}
    if M is not None:
        system["M"] = M
    data = {"name": "hm", "system": system, "mu": 0.5, "analyses": list(analyses)}
    if limits:
        data["settings"] = {"limits": limits}
    path = tmp_path / "scene.yaml"
    path.write_text(yaml.safe_dump(data))
    return str(path)


@pytest.mark.parametrize("command", ["validate", "run"])
def test_petsc_info_sidecar_injection_does_nothing(tmp_path, command):
    """A ``K.petsc.info`` asking PETSc to write files is ignored on validate and run."""
    _petsc_write(tmp_path / "K.petsc", _chain(6))
    marker, log = tmp_path / "MARKER", tmp_path / "LOG"
    (tmp_path / "K.petsc.info").write_text(f"-mat_view ascii:{marker}\n-log_view :{log}\n-vec_view ascii:{marker}\n")
    scene = _scene(tmp_path, "K.petsc")
    args = [command, scene] + (["-o", str(tmp_path / "out"), "-q"] if command == "run" else [])
    proc = run_cli(*args, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert not marker.exists() and not log.exists()


def test_petsc_binary_read_without_petsc_equals_petsc(tmp_path):
    from app.systems.matrices.files import read_petsc
    A = sp.random(40, 40, density=0.2, random_state=1, format="csr") + sp.identity(40)
    _petsc_write(tmp_path / "A.petsc", A)
    assert abs(read_petsc(tmp_path / "A.petsc", "matrix") - A).max() == 0


@pytest.mark.parametrize("fmt", ["mtx", "petsc"])
def test_huge_header_refused_in_under_a_second(tmp_path, fmt):
    """A header declaring 1e12 rows: one line naming the file and the key, before any allocation."""
    if fmt == "mtx":
        (tmp_path / "K.mtx").write_text("%%MatrixMarket matrix coordinate real general\n"
                                        "1000000000000 1000000000000 1000000000000\n1 1 1.0\n")
        name = "K.mtx"
    else:
        (tmp_path / "K.petsc").write_bytes(struct.pack(">4i", 1211216, 2**31 - 1, 2**31 - 1, 2**31 - 1))
        name = "K.petsc"
    t0 = time.monotonic()
    proc = run_cli_here("validate", _scene(tmp_path, name), cwd=tmp_path)
    line = one_error_line(proc)
    assert f"system.K = '{name}'" in line and "max_dofs" in line, line
    assert time.monotonic() - t0 < 10                         # CLI start-up included
    from app.systems.matrices.schema import read_matrix
    from app.systems.schema import Limits, SystemPathError
    t0 = time.monotonic()
    with pytest.raises(SystemPathError, match="max_dofs"):
        read_matrix("K", name, tmp_path / name, Limits())
    assert time.monotonic() - t0 < 1.0


def test_header_beyond_memory_is_exit_4(tmp_path):
    (tmp_path / "K.mtx").write_text("%%MatrixMarket matrix coordinate real general\n100000 100000 2\n1 1 1.0\n2 2 1.0\n")
    line = one_error_line(run_cli_here("validate", _scene(tmp_path, "K.mtx", limits={"max_memory_gb": 1e-6}), cwd=tmp_path), 4)
    assert "K.mtx" in line and "max_memory_gb" in line


def test_header_promising_more_than_the_file_holds(tmp_path):
    (tmp_path / "K.mtx").write_text("%%MatrixMarket matrix coordinate real general\n1000 1000 900000\n1 1 1.0\n")
    line = one_error_line(run_cli_here("validate", _scene(tmp_path, "K.mtx"), cwd=tmp_path))
    assert "K.mtx" in line and "cut off" in line


def test_three_dimensional_npy_isone_error_line(tmp_path):
    np.save(tmp_path / "K.npy", np.ones((2, 2, 2)))
    line = one_error_line(run_cli_here("validate", _scene(tmp_path, "K.npy"), cwd=tmp_path))
    assert "system.K = 'K.npy'" in line and "dimensions" in line


def test_singular_K_of_3000_dofs_refused(tmp_path):
    scipy.io.mmwrite(str(tmp_path / "K.mtx"), _chain(3000, held=False))
    line = one_error_line(run_cli_here("validate", _scene(tmp_path, "K.mtx"), cwd=tmp_path))
    assert "system.K = 'K.mtx'" in line and "singular" in line, line


def test_indefinite_K_of_3000_dofs_refused(tmp_path):
    scipy.io.mmwrite(str(tmp_path / "K.mtx"), (_chain(3000) - 0.5 * sp.identity(3000)).tocsr())
    line = one_error_line(run_cli_here("validate", _scene(tmp_path, "K.mtx"), cwd=tmp_path))
    assert "negative eigenvalue" in line, line


@pytest.mark.parametrize("mass, words", [
    (lambda n: -2 * sp.identity(n, format="csr"), "<= 0"),
    (lambda n: sp.diags(np.r_[0.0, np.ones(n - 1)]).tocsr(), "<= 0"),
    (lambda n: (sp.identity(n) + 0.6 * sp.diags([np.ones(n - 1), np.ones(n - 1)], [-1, 1])).tocsr(),
     "negative eigenvalue"),
])
def test_meaningless_M_of_3000_dofs_refused(tmp_path, mass, words):
    scipy.io.mmwrite(str(tmp_path / "K.mtx"), _chain(3000))
    scipy.io.mmwrite(str(tmp_path / "M.mtx"), mass(3000))
    line = one_error_line(run_cli_here("validate", _scene(tmp_path, "K.mtx", "M.mtx", analyses=("sufficient",)), cwd=tmp_path))
    assert "system.M = 'M.mtx'" in line and words in line, line


def test_validate_reports_the_real_sizes_of_a_matrices_scene(tmp_path):
    scipy.io.mmwrite(str(tmp_path / "K.mtx"), _chain(30))
    proc = run_cli_here("validate", _scene(tmp_path, "K.mtx"), cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert "30 DOFs, 1 contact nodes" in proc.stdout, proc.stdout


@pytest.mark.parametrize("scale", [1e308, 1e-308])
def test_matrix_entries_out_of_range_refused(tmp_path, scale):
    scipy.io.mmwrite(str(tmp_path / "K.mtx"), sp.csr_matrix(scale * np.eye(4)))
    line = one_error_line(run_cli_here("validate", _scene(tmp_path, "K.mtx", analyses=("enumerate",)), cwd=tmp_path))
    assert "system.K = 'K.mtx'" in line and "rescale the units" in line, line


def test_no_free_dof_is_stated_plainly(tmp_path):
    """Every DOF a stuck contact DOF: no PETSc error code, the plain reason."""
    scipy.io.mmwrite(str(tmp_path / "K.mtx"), sp.csr_matrix(np.array([[2.0, -1.0], [-1.0, 2.0]])))
    scipy.io.mmwrite(str(tmp_path / "M.mtx"), sp.identity(2, format="csr"))
    scene = _scene(tmp_path, "K.mtx", "M.mtx", analyses=("necessary", "sufficient", "mceip_mu"))
    proc = run_cli("run", scene, "-o", str(tmp_path / "out"), cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert "nothing can move: every DOF is fixed or stuck" in proc.stdout and "error code" not in proc.stdout
