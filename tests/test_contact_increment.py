"""The contact increment (app/loading/contact.py): its vectorised Jacobian against the law written
node by node, and the same equilibrium from a cold start and from the previous slip."""
from __future__ import annotations

import numpy as np
import pytest
from petsc4py import PETSc

from app.loading.contact import FrictionalContact


def _stiffness(n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(2 * n, 2 * n))
    return A @ A.T + 2 * n * np.eye(2 * n)


def _loop_jacobian(fc: FrictionalContact, z: np.ndarray) -> np.ndarray:
    """The generalised Jacobian of the increment, one node at a time (stick / slip / no pressure)."""
    n, mu = fc.n, fc.mu
    r = fc._reactions(z)
    rT, p = r[0::2], -r[1::2]
    w = rT - z[n:]
    dT, dN = fc.KP[0::2], fc.KP[1::2]
    J = np.zeros((2 * n, 2 * n))
    J[:n] = -dN
    for i in range(n):
        b = mu * max(p[i], 0.0)
        if -b < w[i] < b:
            J[n + i, n + i] = 1.0
        elif p[i] > 0:
            J[n + i] = dT[i] + (mu if w[i] >= b else -mu) * dN[i]
        else:
            J[n + i] = dT[i]
    return J


@pytest.mark.parametrize("seed", range(4))
def test_jacobian_matches_the_law_node_by_node(seed):
    n = 12
    rng = np.random.default_rng(100 + seed)
    with FrictionalContact(_stiffness(n, seed), 0.4) as fc:
        fc.base = rng.normal(size=2 * n)
        z = np.concatenate([np.abs(rng.normal(size=n)), rng.normal(size=n)])
        X = PETSc.Vec().createSeq(2 * n, comm=PETSc.COMM_SELF)
        try:
            X.setArray(z)
            fc._jacobian(None, X, fc.J, fc.J)
            got = fc.J.getDenseArray().copy()
        finally:
            X.destroy()
        r = fc._reactions(z)
        p, w = -r[1::2], r[0::2] - z[n:]
        b = fc.mu * np.maximum(p, 0.0)
        kinds = {"stick": (-b < w) & (w < b), "slip+": (w >= b) & (p > 0), "slip-": (w <= -b) & (p > 0),
                 "no pressure": p <= 0}
        assert all(k.any() for k in kinds.values()), {k: int(v.sum()) for k, v in kinds.items()}
        np.testing.assert_array_equal(got, _loop_jacobian(fc, z))


def test_start_from_previous_slip_gives_the_same_equilibrium():
    n = 10
    Kc = _stiffness(n, 7)
    rng = np.random.default_rng(8)
    u0 = np.zeros(2 * n)
    u0[1::2] = -np.abs(rng.normal(size=n)) * 0.1        # pressed into the foundation
    u0[0::2] = 0.2 * rng.normal(size=n)
    with FrictionalContact(Kc, 0.3) as fc:
        first = fc.solve(u0, np.zeros(n), np.zeros(n))
        assert np.any(np.abs(first.slip_increment) > 1e-6)          # some nodes slide
        u1 = u0 + np.tile([0.05, 0.0], n)
        cold = fc.solve(u1, first.u_T, -first.u_N)
        warm = fc.solve(u1, first.u_T, -first.u_N, first.slip_increment)
    assert warm.iterations <= cold.iterations
    for a, b in ((warm.r_T, cold.r_T), (warm.r_N, cold.r_N), (warm.u_T, cold.u_T), (warm.u_N, cold.u_N)):
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-10 * max(np.max(np.abs(b)), 1.0))



def test_a_start_far_from_the_solution_reaches_the_cold_start_equilibrium():
    """An increment started far from its solution (previous gaps of 100, now closed): the absolute
    tolerance is then the rounding of the residual at the start (``rounding_floor``, far above
    1e-14 of the reactions), and Newton still reaches the cold start's equilibrium in its first
    run. (The case that needs the floor, a mesh graded towards a corner, is
    tests/test_refinement.py ``test_a_graded_corner_resolves_the_stick_zone``.)"""
    n = 40
    Kc = _stiffness(n, 3)
    rng = np.random.default_rng(4)
    u0 = np.zeros(2 * n)
    u0[1::2] = np.abs(rng.normal(size=n)) * 0.1          # pressed into the foundation
    u0[0::2] = 0.03 * rng.normal(size=n)
    with FrictionalContact(Kc, 0.3) as fc:
        ref = fc.solve(u0, np.zeros(n), np.zeros(n))
        far = fc.solve(u0, np.zeros(n), np.full(n, 100.0))
        assert fc.rounding_floor(np.concatenate([np.full(n, 100.0), np.zeros(n)])) > 100 * 1e-14 * np.max(np.abs(fc.base))
    stuck = np.abs(ref.slip_increment) < 1e-12
    assert stuck.any() and not stuck.all() and np.any(ref.r_N < 0)    # stick and slip, in contact
    assert far.method == "vinewtonrsls" and far.iterations <= 10, (far.method, far.iterations)
    scale = np.max(np.abs(ref.r_N))
    for a, b in ((far.r_T, ref.r_T), (far.r_N, ref.r_N)):
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-9 * scale)
    np.testing.assert_allclose(far.slip_increment, ref.slip_increment, rtol=0, atol=1e-9)
