"""Two deformable bodies in closed form: the paper's two particles (Fig. 1) resting on a third particle
held by springs k_T, k_N to the ground (``system.support``), both in impending slip.

Derivation (docs/method.md section 10), in units of k, c = cos(phi), s = sin(phi), alpha = k_T / k,
beta = k_N / k. The contact DOFs are relative, q_i = u_i - v; the support v is an interior node.
Condensing v from the energy 1/2 (q + E v)^T K (q + E v) + 1/2 v^T K_s v (E = [I; I]) gives the
contact stiffness

    S = K - h_T h_T^T / g_T - h_N h_N^T / g_N,   g_T = 2 c^2 + alpha,  g_N = 2 s^2 + 2 + beta,
    h_T = (c^2, -c s, c^2, c s),  h_N = (-c s, s^2 + 1, c s, s^2 + 1)    (order T1, N1, T2, N2),

since E^T K E = diag(2 c^2, 2 s^2 + 2) and the rows of E^T K are h_T, h_N. With both normal relative
DOFs held at zero, the reduced MCEIP-mu on x = (S1 q_T1, S2 q_T2) reads

    A(mu) x = y,  A_ij = S_i S_j (S[T_i, T_j] + mu S_i S[N_i, T_j]),  0 <= x ⊥ y >= 0,

as Table 1 with S for K (tests/test_two_particles.py; alpha, beta -> inf gives it back):
slip-stick A_11(mu) = 0 with A_21 >= 0; stick-slip A_22(mu) = 0 with A_12 >= 0; slip-slip
det A(mu) = 0 (a quadratic in mu) with x_2 / x_1 = -A_11 / A_12 > 0.
"""
import math

import numpy as np
import pytest
from conftest import run_scene
from test_two_particles import analytic_mu

PHI = 35.0


def contact_stiffness(phi: float, alpha: float, beta: float) -> np.ndarray:
    """S above, by the closed form (entries written out)."""
    c, s = math.cos(math.radians(phi)), math.sin(math.radians(phi))
    K = np.array([[c * c + 1, -c * s, -1.0, 0.0], [-c * s, s * s + 1, 0.0, 0.0],
                  [-1.0, 0.0, c * c + 1, c * s], [0.0, 0.0, c * s, s * s + 1]])
    hT = np.array([c * c, -c * s, c * c, c * s])
    hN = np.array([-c * s, s * s + 1, c * s, s * s + 1])
    return K - np.outer(hT, hT) / (2 * c * c + alpha) - np.outer(hN, hN) / (2 * s * s + 2 + beta)


def analytic_mu_supported(phi, S1, S2, alpha, beta):
    S = contact_stiffness(phi, alpha, beta)
    sg = (S1, S2)
    T, N = (0, 2), (1, 3)
    # A(mu) = A0 + mu A1, entries as in the module docstring
    A0 = np.array([[sg[i] * sg[j] * S[T[i], T[j]] for j in range(2)] for i in range(2)])
    A1 = np.array([[sg[j] * S[N[i], T[j]] for j in range(2)] for i in range(2)])     # S_i^2 = 1
    sols = []
    for i, j, pat in ((0, 1, ["slip", "stick"]), (1, 0, ["stick", "slip"])):
        mu = -A0[i, i] / A1[i, i]
        if mu >= 0 and A0[j, i] + mu * A1[j, i] >= 0:
            x = (1.0, 0.0) if i == 0 else (0.0, 1.0)
            sols.append((mu, x, pat))
    # det(A0 + mu A1) = 0: a quadratic in mu
    a2 = A1[0, 0] * A1[1, 1] - A1[0, 1] * A1[1, 0]
    a1 = A0[0, 0] * A1[1, 1] + A1[0, 0] * A0[1, 1] - A0[0, 1] * A1[1, 0] - A1[0, 1] * A0[1, 0]
    a0 = A0[0, 0] * A0[1, 1] - A0[0, 1] * A0[1, 0]
    for mu in np.roots([a2, a1, a0]):
        if abs(mu.imag) > 1e-12 or mu.real < 0:
            continue
        mu = mu.real
        A = A0 + mu * A1
        ratio = -A[0, 0] / A[0, 1]
        if ratio > 0:
            sols.append((mu, (1 / (1 + ratio), ratio / (1 + ratio)), ["slip", "slip"]))
    return sorted(sols, key=lambda t: (t[0], t[2]))


def scene(signs, alpha, beta, k=1000.0):
    return {"name": "sp", "mu": 3.0, "analyses": ["mceip_mu"],
            "system": {"type": "two_particles", "k": k, "m": 2.0, "phi_deg": PHI, "signs": list(signs),
                       "support": {"k_T": alpha * k, "k_N": beta * k, "m": 3.0}}}


@pytest.mark.parametrize("signs", [(1, 1), (-1, -1), (1, -1), (-1, 1)])
def test_the_closed_form_is_table_1_for_a_rigid_support(signs):
    got = analytic_mu_supported(PHI, *signs, 1e12, 1e12)
    want = analytic_mu(PHI, *signs)
    assert len(got) == len(want)
    for (v, x, p), (w, y, q) in zip(got, want):
        assert v == pytest.approx(w, rel=1e-9) and p == q and np.allclose(x, y, atol=1e-9)


@pytest.mark.parametrize("signs", [(1, 1), (-1, -1), (1, -1), (-1, 1)])
@pytest.mark.parametrize("alpha, beta", [(0.5, 2.0), (3.0, 0.2), (1.0, 1.0)])
def test_the_app_finds_the_closed_form_solutions_on_a_supported_particle(signs, alpha, beta):
    expected = analytic_mu_supported(PHI, *signs, alpha, beta)
    res = run_scene(scene(signs, alpha, beta))
    block = res["states"][0]["analyses"]["mceip_mu"]
    found = sorted(block["solutions"], key=lambda s: (s["value"], s["pattern"]))
    # the app lists the solutions on [0, mu_max]; the closed form has all of them
    mu_max = block["mu_max"] if "mu_max" in block else max([v for v, _, _ in expected] + [0.0]) + 1
    expected = [e for e in expected if e[0] <= mu_max]
    assert len(found) == len(expected), (found, expected)
    for f, (v, x, pat) in zip(found, expected):
        assert f["value"] == pytest.approx(v, rel=1e-8, abs=1e-12)
        assert f["pattern"] == pat
        assert np.allclose(np.array(f["x_Ts"]) / np.sum(f["x_Ts"]), x, atol=1e-8)
    assert "supported particle" in res["system"]


def test_a_softer_support_changes_the_onset():
    """The support's compliance moves the equal-sign onset away from Table 1's sqrt(c^2 + 2) / s."""
    rigid = analytic_mu(PHI, 1, 1)
    soft = analytic_mu_supported(PHI, 1, 1, 0.5, 0.5)
    assert rigid and soft and abs(soft[0][0] - rigid[0][0]) > 1e-3 * rigid[0][0]
