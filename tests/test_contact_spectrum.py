"""The values of the necessary condition (19) from the contact DOFs (app/analyses/conditions/contact_spectrum.py,
docs/method.md section 2) against the full-size eigenvalues: LAPACK on the app's own reduced
pencils, SLEPc along whole paths, random SPD matrices, one and two ranks."""
from __future__ import annotations

import copy
import re

import numpy as np
import pytest
import scipy.sparse
from conftest import ROOT, run_scene
from mpi4py import MPI
from petsc4py import PETSc
from test_dynamic_contact import BLOCK

from app.analyses.conditions import contact_spectrum as cs
from app.analyses.pencils.kept_contact import KeptContact
from app.analyses.pencils.reduced import combine, dense
from app.analyses.pencils.state import StatePencils
from app.common.stages import Stages
from app.loading.classify import FREE, SLIP, STICK, Classification
from app.scene.schema import parse_scene
from app.systems.block.path import build


def _cls(status, signs=None):
    return Classification(status=tuple(status),
                          signs=tuple(signs if signs is not None else (1 if s == SLIP else 0 for s in status)))


def _cases(n):
    out = [_cls([STICK] * n), _cls([SLIP] * n), _cls([STICK] * (n - 1) + [SLIP]),
           _cls([STICK] * (n // 2) + [SLIP] * (n - n // 2)),
           _cls([FREE] * 2 + [SLIP] * (n - 4) + [FREE] * 2), _cls([FREE] + [STICK] * (n - 2) + [FREE]),
           _cls([SLIP] * (n // 2) + [STICK] * (n - n // 2), [-1] * (n // 2) + [0] * (n - n // 2))]
    return out


@pytest.mark.parametrize("nx", [10, 20])
def test_values_equal_the_full_size_eigenvalues(nx):
    """Stick, slip (both directions), free and mixed classifications at three mu: the value and the
    scale it is reported against equal LAPACK's smallest eigenvalue and the largest diagonal entry
    of the app's reduced ``sym K*(mu)``, ``sym M*(mu)`` (1e-10 of the scale)."""
    sc = copy.deepcopy(BLOCK)
    sc["system"].update(nx=nx, ny=nx // 2)
    with build(parse_scene(sc).system, MPI.COMM_WORLD, Stages()) as system:
        dofs = np.array([[nd.dof_T, nd.dof_N] for nd in system.nodes]).ravel()
        signs = np.array([[nd.sign_T, nd.sign_N] for nd in system.nodes], dtype=float).ravel()
        spectra = {"K": cs.build(system.K, dofs, signs), "M": cs.build(system.mass(), dofs, signs)}
        assert len(spectra["K"].poles) == 1 and len(spectra["M"].poles) == 0   # K has a gap, M a cluster
        below = 0
        for cls in _cases(len(system.nodes)):
            for mu in (0.3, 1.1, 3.0):
                p = StatePencils(system, cls)
                try:
                    for name, (A0, A1) in (("K", p.K()), ("M", p.M())):
                        A = dense(combine(A0, A1, mu))
                        A = 0.5 * (A + A.T)
                        lam = np.linalg.eigvalsh(A)[0]
                        scale = np.abs(np.diag(A)).max()
                        v = cs.value(spectra[name], cls, mu)
                        assert v is not None, (name, cls.counts(), mu)
                        assert abs(v.value - lam) <= 1e-10 * scale, (name, cls.counts(), mu, v.value, lam)
                        assert v.scale == pytest.approx(scale, rel=1e-14)
                        below += v.value < spectra[name].k1 * (1 - 1e-9)
                finally:
                    p.destroy()
        assert below > 10              # roots strictly below the first pole, not only k_1
        # the pieces are shared: far fewer factorisations than classifications x 2
        assert spectra["K"].evaluations + spectra["M"].evaluations < 120


@pytest.mark.parametrize("nx", [10, 20])
def test_the_mass_matrix_interior_from_a_rough_value_without_factorisation(nx, monkeypatch):
    """``k_1`` of the mass matrix's interior block from the unshifted rough value (``mass=True``:
    no factorisation) is LAPACK's smallest eigenvalue of ``M_ii`` (1e-10 relative), as is the one
    from the shift-and-invert rough value; where the unshifted solve does not converge (a budget
    of one restart) the shift-and-invert rough value is used, with the same ``k_1``."""
    from app.analyses.conditions import interior_modes as im
    sc = copy.deepcopy(BLOCK)
    sc["system"].update(nx=nx, ny=nx // 2)
    with build(parse_scene(sc).system, MPI.COMM_WORLD, Stages()) as system:
        dofs = np.array([[nd.dof_T, nd.dof_N] for nd in system.nodes]).ravel()
        signs = np.array([[nd.sign_T, nd.sign_N] for nd in system.nodes], dtype=float).ravel()
        M = system.mass()
        Md = dense(M)
        inner = np.setdiff1d(np.arange(len(Md)), dofs)
        want = np.linalg.eigvalsh(Md[np.ix_(inner, inner)])[0]
        rough = []
        unshifted = im._unshifted
        monkeypatch.setattr(im, "_unshifted", lambda X: rough.append(unshifted(X)) or rough[-1])
        for mass, restarts in ((False, im.UNSHIFTED_RESTARTS), (True, im.UNSHIFTED_RESTARTS), (True, 1)):
            monkeypatch.setattr(im, "UNSHIFTED_RESTARTS", restarts)
            got = cs.build(M, dofs, signs, mass=mass)
            assert got.k1 == pytest.approx(want, rel=1e-10), (mass, restarts)
            assert len(got.poles) == 0
        assert len(rough) == 2 and rough[0] is not None and rough[1] is None
        assert rough[0] == pytest.approx(want, rel=1e-4) and rough[0] >= want * (1 - 1e-12)   # a Ritz value


def test_rough_pairs_within_the_rounding_of_their_residuals_are_kept(monkeypatch):
    """The stiffness matrix's rough pairs are kept without a second solve where their residuals
    are within the rounding of the residuals themselves, though above ``tol`` (here 1e-16, below
    any residual), and they are LAPACK's (values to 1e-10, vectors to 1e-8); with no rounding
    allowed the second solve runs."""
    from app.analyses.conditions import interior_modes as im
    sc = copy.deepcopy(BLOCK)
    sc["system"].update(nx=20, ny=10)
    with build(parse_scene(sc).system, MPI.COMM_WORLD, Stages()) as system:
        dofs = np.array([[nd.dof_T, nd.dof_N] for nd in system.nodes]).ravel()
        inner = np.setdiff1d(np.arange(system.n_dofs), dofs).astype(PETSc.IntType)
        rows = PETSc.IS().createGeneral(inner, comm=PETSc.COMM_SELF)
        (Kii,) = system.K.createSubMatrices(rows, rows)
        rows.destroy()
        w, V = np.linalg.eigh(dense(Kii))
        solves = []
        solve = im._solve
        monkeypatch.setattr(im, "_solve", lambda *a, **kw: solves.append(kw.get("start")) or solve(*a, **kw))
        for floor, count in ((im.residual_floor, 1), (lambda X, k: np.zeros(len(k)), 2)):
            monkeypatch.setattr(im, "residual_floor", floor)
            solves.clear()
            k, vecs = im.interior_modes(Kii, cs.GAP, 1e-16)
            assert len(solves) == count
            assert k[:2] == pytest.approx(w[:2], rel=1e-10)
            assert abs(vecs[:, 0] @ V[:, 0]) == pytest.approx(1.0, abs=1e-8)
        Kii.destroy()


def _random_system(rng, n_inner: int, n_nodes: int):
    """A random sparse SPD matrix (a shifted graph Laplacian with random weights) whose last
    ``2 n_nodes`` DOFs are the contact DOFs."""
    N = n_inner + 2 * n_nodes
    A = scipy.sparse.random(N, N, density=6.0 / N, random_state=rng)
    A = A + A.T + scipy.sparse.diags(rng.uniform(0.0, 1.0, N))
    L = scipy.sparse.diags(np.asarray(abs(A).sum(axis=1)).ravel()) - A
    X = (L + scipy.sparse.identity(N) * rng.uniform(0.05, 0.5)).tocsr()
    X.sort_indices()
    P = PETSc.Mat().createAIJ(X.shape, csr=(X.indptr.astype(PETSc.IntType), X.indices.astype(PETSc.IntType), X.data),
                              comm=PETSc.COMM_SELF)
    P.assemble()
    dofs = np.arange(n_inner, N)
    signs = rng.choice([-1.0, 1.0], size=2 * n_nodes)
    return X.toarray(), P, dofs, signs


@pytest.mark.parametrize("seed", range(6))
def test_random_spd_matrices(seed):
    """Random SPD matrices and random classifications: the value is the smallest eigenvalue of the
    symmetric matrix of the definition, ``[[X_ii, X_ic P], [P^T X_ci, sym(R X_cc Q)]]`` (dense)."""
    rng = np.random.default_rng(seed)
    n_nodes = int(rng.integers(3, 9))
    Xd, X, dofs, signs = _random_system(rng, int(rng.integers(40, 160)), n_nodes)
    try:
        sc = cs.build(X, dofs, signs)
        inner = np.setdiff1d(np.arange(len(Xd)), dofs)
        Xii = Xd[np.ix_(inner, inner)]
        Xic = Xd[np.ix_(inner, dofs)] * signs[None, :]
        Xcc = signs[:, None] * Xd[np.ix_(dofs, dofs)] * signs[None, :]
        for _ in range(6):
            status = rng.choice([STICK, SLIP, FREE], size=n_nodes)
            sg = [int(rng.choice([-1, 1])) if s == SLIP else 0 for s in status]
            cls = _cls(status, sg)
            mu = float(rng.uniform(0.0, 2.0))
            kc = KeptContact(len(dofs), cls, mu)
            P = (0.5 * (kc.Q + kc.R)).toarray()
            A0 = kc.sandwich(kc.R, Xcc, kc.Q)
            A = np.block([[Xii, Xic @ P], [P.T @ Xic.T, 0.5 * (A0 + A0.T)]])
            lam = np.linalg.eigvalsh(A)[0]
            scale = np.abs(np.diag(A)).max()
            v = cs.value(sc, cls, mu)
            if v is None:           # left to the full-size solve: allowed, never a wrong value
                continue
            assert abs(v.value - lam) <= 1e-10 * scale, (seed, cls.counts(), mu, v.value, lam)
    finally:
        X.destroy()


def _necessary_values(results):
    return [(s["index"], s["analyses"]["necessary"]) for s in results["states"]
            if s.get("analyses_shared_with") is None and isinstance((s.get("analyses") or {}).get("necessary"), dict)
            and "min_eig_K_sym" in s["analyses"]["necessary"]]


def _same_values(full, contact, rtol=1e-10):
    a, b = _necessary_values(full), _necessary_values(contact)
    assert [i for i, _ in a] == [i for i, _ in b] and len(a) >= 3
    for (i, x), (_, y) in zip(a, b):
        for name in ("K", "M"):
            assert abs(x[f"min_eig_{name}_sym_relative"] - y[f"min_eig_{name}_sym_relative"]) <= rtol, (i, name)
        assert x["satisfied"] == y["satisfied"], i


def _with(scene: dict, min_dofs: int) -> dict:
    sc = copy.deepcopy(scene)
    sc.setdefault("settings", {}).setdefault("eig", {})["necessary_contact_min_dofs"] = min_dofs
    return sc


def test_whole_path_of_the_block():
    """Every classification of the block's study: the contact-DOF values equal SLEPc's full-size
    ones (values relative to the scale, 1e-10) and decide (19) alike."""
    sc = copy.deepcopy(BLOCK)
    sc["analyses"] = ["necessary"]
    _same_values(run_scene(_with(sc, 10**9)), run_scene(_with(sc, 0)))


def test_whole_path_of_a_gmsh_body(tmp_path):
    """The same on the shipped Gmsh block (its own mesh, the press-and-drag program, shortened)."""
    import yaml
    src = ROOT / "app" / "scenes" / "gmsh"
    text = re.sub(r"^outputs:.*$", "", (src / "block.yaml").read_text(), flags=re.M)
    data = yaml.safe_load(text)
    data["system"]["file"] = str(src / "block.geo")
    data["system"]["program"][1]["steps"] = 150
    data["analyses"] = ["necessary"]
    _same_values(run_scene(_with(data, 10**9)), run_scene(_with(data, 0)))


@pytest.mark.parametrize("evaluations", [1, 6, 30])
def test_a_spent_budget_gives_bounds_that_hold_the_values(evaluations):
    """``eig.necessary_value_work`` caps the exact Schur complements per matrix; once spent a value
    is reported as bounds (docs/method.md section 2). Along the 20 x 10 block's path at three
    budgets: every bound holds the value computed without a budget (SLEPc's full-size eigenvalue,
    an independent computation), (19) is decided alike, and MCEIP-lambda^2 (whose search bound
    then comes from the lower bounds) answers alike."""
    sc = copy.deepcopy(BLOCK)
    sc["system"].update(nx=20, ny=10)
    sc["analyses"] = ["necessary", "mceip_lambda2"]
    full = run_scene(_with(sc, 10**9))
    capped = _with(sc, 0)
    dofs = 2 * 21 * 11
    capped["settings"]["eig"]["necessary_value_work"] = float(evaluations * dofs)
    got = run_scene(capped)
    bounded = 0
    for sa, sb in zip(full["states"], got["states"]):
        x, y = (sa.get("analyses") or {}).get("necessary"), (sb.get("analyses") or {}).get("necessary")
        if not isinstance(x, dict) or "min_eig_K_sym" not in x:
            continue
        assert x["satisfied"] == y["satisfied"]
        for name in ("K", "M"):
            v = x[f"min_eig_{name}_sym"]
            if y[f"min_eig_{name}_sym"] is None:
                bounded += 1
                lo, hi = y[f"min_eig_{name}_sym_bounds"]
                assert lo - 1e-9 * abs(v) <= v <= hi + 1e-9 * abs(v), (name, lo, v, hi)
                assert lo <= hi and (hi <= 0 or lo >= 0)            # the sign decided
            else:
                assert abs(y[f"min_eig_{name}_sym_relative"] - x[f"min_eig_{name}_sym_relative"]) <= 1e-10
        la, lb = sa["analyses"].get("mceip_lambda2"), sb["analyses"].get("mceip_lambda2")
        if isinstance(la, dict):
            assert la["result"] == lb["result"]
    assert bounded > 0


def test_two_ranks(tmp_path):
    """K and M gathered on rank 0, which alone computes the values: the same as one rank and as the
    full-size solve."""
    import yaml
    from conftest import results_on_ranks
    sc = copy.deepcopy(BLOCK)
    sc["analyses"] = ["necessary"]
    path = tmp_path / "scene.yaml"
    path.write_text(yaml.safe_dump(_with(sc, 0)))
    runs = results_on_ranks(path, tmp_path)
    _same_values(runs[1], runs[2], rtol=1e-12)
    _same_values(run_scene(_with(sc, 10**9)), runs[2])


def test_flushing_subnormals_leaves_the_schur_complement_unchanged():
    """MUMPS's factor of a well-conditioned matrix (a mass matrix, K + t M at large t) decays
    exponentially through nested dissection's fill and underflows into subnormals at 10^6 DOFs,
    which x86 computes some 100x slower: the Schur complements flush them to zero
    (app/linalg.py flush_subnormals). Here a 5-point matrix whose off-diagonal ratio 2.5e-4 makes
    fill entries 90 nodes apart underflow: the Schur complement onto a row of the grid equals the
    one computed with gradual underflow, and the floating-point environment is restored."""
    import numpy as np
    import scipy.sparse as sp
    from petsc4py import PETSc

    from app.linalg import flush_subnormals
    from app.loading.mumps_schur import SchurComplements

    tiny = np.array([1e-300])
    with flush_subnormals():
        assert (tiny * 1e-10)[0] == 0.0
        with flush_subnormals():
            assert (tiny * 1e-10)[0] == 0.0
        assert (tiny * 1e-10)[0] == 0.0
    assert (tiny * 1e-10)[0] == 1e-310
    n = 100
    one = sp.diags([-1e-3, 4.0, -1e-3], [-1, 0, 1], shape=(n, n))
    A = (sp.kron(sp.eye(n), one) + sp.kron(sp.diags([-1e-3, -1e-3], [-1, 1], shape=(n, n)), sp.eye(n))).tocsr()
    rows = np.arange(n // 2 * n, n // 2 * n + n)
    P = PETSc.Mat().createAIJ(A.shape, csr=(A.indptr, A.indices, A.data), comm=PETSc.COMM_SELF)
    try:
        with SchurComplements(P, rows, "cd_shifted_") as schur:
            flushed = schur()
        # the same elimination with gradual underflow: MUMPS through a plain LU solve of the interior
        inner = np.setdiff1d(np.arange(n * n), rows)
        dense = A[rows][:, rows].toarray() - A[rows][:, inner] @ sp.linalg.splu(A[inner][:, inner].tocsc()).solve(
            A[inner][:, rows].toarray())
    finally:
        P.destroy()
    assert np.allclose(flushed, dense, rtol=0, atol=1e-15 * np.abs(dense).max())


@pytest.mark.parametrize("name", ["half_disk_cylinder.yaml", "half_disk_seat.yaml"])
def test_whole_path_on_a_curved_obstacle(name):
    """A curved obstacle (a convex cylinder and a concave seat): the slip nodes' contact frames
    rotate and K* carries the curvature term (1 + mu^2) G (docs/method.md section 8); the
    contact-DOF values equal SLEPc's full-size ones along the whole path."""
    import yaml
    src = ROOT / "app" / "scenes" / "gmsh"
    data = yaml.safe_load(re.sub(r"^outputs:.*$", "", (src / name).read_text(), flags=re.M))
    data["system"]["file"] = str(src / data["system"]["file"])
    data["analyses"] = ["necessary"]
    full, contact = run_scene(_with(data, 10**9)), run_scene(_with(data, 0))
    _same_values(full, contact)
    # the contact-DOF values took every classification: no full-size solve ran
    assert "necessary condition (19) on the contact DOFs" in str(contact["stages"])
    assert "'necessary condition (19)'" not in str(contact["stages"]), contact["stages"]
