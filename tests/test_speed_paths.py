"""The faster paths of issue 14 give the answers of the paths they replace.

- the necessary condition's smallest eigenvalue (19) with a warm-start hint: right with a good
  hint, a hint inside the spectrum (the first shift is not below it) and no hint;
- the batched semismooth Newton of the condensed MCEIP-mu: a stack holding singular Jacobians
  gets the least-squares step for those only, the solve for the others;
- the dense search's iterates against a plain reference implementation of the same method
  (full-step test, then halvings, one row at a time).
"""
import numpy as np
import pytest
from petsc4py import PETSc

from app.analyses.conditions import full_size
from app.analyses.mceip_mu import candidates
from app.scene.sections import EigSettings


def _laplacian(n: int, shift: float) -> PETSc.Mat:
    """1D Laplacian minus ``shift`` (tridiagonal, eigenvalues 2 - 2 cos(k pi / (n + 1)) - shift)."""
    A = PETSc.Mat().createAIJ((n, n), nnz=3, comm=PETSc.COMM_SELF)
    for i in range(n):
        A.setValue(i, i, 2.0 - shift)
        if i > 0:
            A.setValue(i, i - 1, -1.0)
        if i < n - 1:
            A.setValue(i, i + 1, -1.0)
    A.assemble()
    return A


@pytest.mark.parametrize("hint", [None, "exact", "inside", "far below"])
def test_min_sym_eig_with_any_hint(hint):
    n, shift = 700, 0.3                       # above EigSettings.dense_limit: the shift-and-invert path
    exact = 2.0 - 2.0 * np.cos(np.pi / (n + 1)) - shift
    h = {None: None, "exact": exact, "inside": 1.7, "far below": -50.0}[hint]
    A = _laplacian(n, shift)
    try:
        lam = full_size.min_sym_eig(A, EigSettings(), h)
    finally:
        A.destroy()
    assert lam == pytest.approx(exact, rel=1e-9, abs=1e-9)


@pytest.mark.parametrize("factor", ["petsc", "mumps"])
def test_warm_shift_is_used_with_either_factorisation(monkeypatch, factor):
    """The warm-started shift below the spectrum is proven by the shift-and-invert solve's own
    factorisation, also when MUMPS makes it (large pencils): PETSc reports a MUMPS factor's inertia
    only with null-pivot detection on, so without it the hint was never used."""
    monkeypatch.setattr(full_size, "MUMPS_MIN_DOFS", 1 if factor == "mumps" else 10**9)
    n, shift = 700, 0.3
    exact = 2.0 - 2.0 * np.cos(np.pi / (n + 1)) - shift
    A = _laplacian(n, shift)
    try:
        lam = full_size._nearest_sym_eig(A, exact - 1e-4, EigSettings(), shift_below=True)
        above = full_size._nearest_sym_eig(A, exact + 1e-2, EigSettings(), shift_below=True)
    finally:
        A.destroy()
    assert lam == pytest.approx(exact, rel=1e-9, abs=1e-9)
    assert above is None                      # a shift inside the spectrum is refused, not solved
    assert not PETSc.Options().hasName("cd_necessary_st_mat_mumps_icntl_24")


def test_newton_steps_isolate_singular_jacobians():
    rng = np.random.default_rng(3)
    J = rng.normal(size=(9, 5, 5))
    J[[2, 7], 4, :] = 0.0                     # two exactly singular Jacobians
    b = rng.normal(size=(9, 5))
    d = candidates._newton_steps(J, b)
    for k in range(9):
        if k in (2, 7):
            ref = np.linalg.lstsq(J[k], b[k], rcond=None)[0]
        else:
            ref = np.linalg.solve(J[k], b[k])
        assert np.allclose(d[k], ref, rtol=1e-10, atol=1e-12)


def _reference_newton(a0, a1, z, max_it=60, tol=1e-13):
    """The method of ``candidates.semismooth_newton`` for one start, written plainly."""
    s = len(z) - 1

    def phi(z):
        x, mu = z[:s], z[s]
        y = a0 @ x + mu * (a1 @ x)
        return np.concatenate([np.minimum(x, y), [min(mu, x.sum() - 1.0)]]), y

    F, y = phi(z)
    its = 0
    for _ in range(max_it):
        nrm = np.linalg.norm(F)
        if not np.isfinite(nrm) or nrm <= tol:
            break
        x, mu = z[:s], z[s]
        J = np.zeros((s + 1, s + 1))
        for i in range(s):
            J[i] = np.eye(s + 1)[i] if x[i] <= y[i] else np.concatenate([a0[i] + mu * a1[i], [a1[i] @ x]])
        J[s] = np.eye(s + 1)[s] if mu <= x.sum() - 1.0 else np.concatenate([np.ones(s), [0.0]])
        try:
            d = np.linalg.solve(J, -F)
        except np.linalg.LinAlgError:
            d = np.linalg.lstsq(J, -F, rcond=None)[0]
        its += 1
        for step in 0.5 ** np.arange(12):
            Fn, yn = phi(z + step * d)
            if np.isfinite(np.linalg.norm(Fn)) and np.linalg.norm(Fn) <= (1 - 1e-4 * step) * nrm:
                z, F, y = z + step * d, Fn, yn
                break
        else:
            break                              # stagnation
    return z, np.linalg.norm(F), its


@pytest.mark.parametrize("seed", range(4))
def test_batched_newton_matches_plain_reference(seed):
    rng = np.random.default_rng(seed)
    s = 6 + 2 * seed
    G = rng.normal(size=(s, s))
    a0 = G @ G.T / s + np.eye(s)
    a1 = rng.normal(size=(s, s)) / np.sqrt(s)
    Z0, _ = candidates._starts(s, [0.5, 2.0, 10.0], [])
    Z, nrm, its = candidates.semismooth_newton(a0, a1, Z0)
    for b in range(len(Z0)):
        z, n, k = _reference_newton(a0, a1, Z0[b].copy())
        assert its[b] == k
        assert (nrm[b] <= 1e-9) == (n <= 1e-9)
        if n <= 1e-9:
            assert np.allclose(Z[b], z, atol=1e-9)
