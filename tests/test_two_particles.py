"""Table 1 of the paper, derived analytically, against the app (MCEIP-lambda^2 and MCEIP-mu).

Pencil of docs/method.md section 4 on (x_T1, x_T2), in units of k, with a = c^2 + 1, b = mu c s,
sigma = S1 S2 and L = lambda^2 m / k:

    [[L + a - b S1, -sigma], [-sigma, L + a + b S2]] x = y,  0 <= x ⊥ y >= 0.

slip-stick (x2 = 0): L = b S1 - a and y2 = -sigma x1 >= 0 (sigma = -1);
stick-slip (x1 = 0): L = -a - b S2 and y1 = -sigma x2 >= 0 (sigma = -1);
slip-slip: (L + a - b S1)(L + a + b S2) = 1 with x2/x1 = sigma (L + a - b S1) > 0.
MCEIP-mu is the same with L = 0 and mu the unknown.
"""
import math

import numpy as np
import pytest
from conftest import run_scene

K, M, PHI = 1000.0, 2.0, 35.0


def analytic_lambda2(k, m, phi, mu, S1, S2):
    c, s = math.cos(math.radians(phi)), math.sin(math.radians(phi))
    a, b, sig = c * c + 1, mu * c * s, S1 * S2
    sols = []
    if sig == -1:
        for L, x, pat in ((b * S1 - a, (1.0, 0.0), ["slip", "stick"]), (-a - b * S2, (0.0, 1.0), ["stick", "slip"])):
            if L >= 0:
                sols.append((L * k / m, x, pat))
    # slip-slip: P = L + a solves (P - b S1)(P + b S2) = 1
    coeffs = [1.0, b * S2 - b * S1, -b * b * S1 * S2 - 1.0]
    for P in np.roots(coeffs):
        if abs(P.imag) > 1e-12:
            continue
        P = P.real
        ratio = sig * (P - b * S1)
        L = P - a
        if ratio > 0 and L >= 0:
            sols.append((L * k / m, (1 / (1 + ratio), ratio / (1 + ratio)), ["slip", "slip"]))
    return sorted(sols, key=lambda t: (t[0], t[2]))


def analytic_mu(phi, S1, S2):
    c, s = math.cos(math.radians(phi)), math.sin(math.radians(phi))
    a, sig, cs = c * c + 1, S1 * S2, c * s
    sols = []
    if sig == -1:
        if S1 == 1:
            sols.append((a / cs, (1.0, 0.0), ["slip", "stick"]))
        if S2 == -1:
            sols.append((a / cs, (0.0, 1.0), ["stick", "slip"]))
    # slip-slip: (a - mu cs S1)(a + mu cs S2) = 1, linear-quadratic in mu
    coeffs = [-cs * cs * S1 * S2, a * cs * (S2 - S1), a * a - 1.0]
    roots = np.roots(coeffs) if abs(coeffs[0]) > 0 else []
    for mu in roots:
        if abs(mu.imag) > 1e-12 or mu.real < 0:
            continue
        mu = mu.real
        ratio = sig * (a - mu * cs * S1)
        if ratio > 0:
            sols.append((mu, (1 / (1 + ratio), ratio / (1 + ratio)), ["slip", "slip"]))
    return sorted(sols, key=lambda t: (t[0], t[2]))


def scene(signs, mu, analyses=("mceip_lambda2", "mceip_mu", "enumerate", "sufficient", "necessary")):
    return {"name": "tp", "system": {"type": "two_particles", "k": K, "m": M, "phi_deg": PHI, "signs": list(signs)},
            "mu": mu, "analyses": list(analyses)}


def assert_same_set(found, expected):
    found = sorted(found, key=lambda s: (s["value"], s["pattern"]))
    assert len(found) == len(expected), (found, expected)
    for f, (v, x, pat) in zip(found, expected):
        assert f["value"] == pytest.approx(v, rel=1e-8, abs=1e-12)
        assert f["pattern"] == pat
        assert np.allclose(f["x_Ts"], x, atol=1e-8)


# (signs, mu, expected number of MCEIP-lambda^2 solutions): Table 1 rows
CASES = [((1, 1), 4.0, 1), ((1, 1), 2.0, 0), ((-1, -1), 4.0, 1), ((-1, -1), 2.0, 0),
         ((-1, 1), 4.0, 0), ((-1, 1), 9.0, 0),
         ((1, -1), 4.5, 2), ((1, -1), 7.0, 3), ((1, -1), 3.0, 0)]


@pytest.mark.parametrize("signs,mu,count", CASES)
def test_table1_lambda2(signs, mu, count):
    expected = analytic_lambda2(K, M, PHI, mu, *signs)
    assert len(expected) == count  # the chosen data really exercise that row of Table 1
    a = run_scene(scene(signs, mu))["states"][0]["analyses"]
    assert_same_set(a["mceip_lambda2"]["solutions"], expected)
    assert_same_set(a["enumerate"]["problems"]["lambda2"]["solutions"], expected)
    for sol in a["mceip_lambda2"]["solutions"]:
        assert sol["residual"] < 1e-8 and sol["complementarity"] < 1e-8


@pytest.mark.parametrize("signs,count", [((1, 1), 1), ((-1, -1), 1), ((-1, 1), 0), ((1, -1), 3)])
def test_table1_mu(signs, count):
    expected = analytic_mu(PHI, *signs)
    assert len(expected) == count
    a = run_scene(scene(signs, 1.0))["states"][0]["analyses"]
    assert_same_set(a["mceip_mu"]["solutions"], expected)
    assert_same_set(a["enumerate"]["problems"]["mu"]["solutions"], expected)


def test_two_modes_share_one_value():
    """S1=+1, S2=-1: slip-stick and stick-slip have the same mu = (c^2+1)/(cs), and both are found."""
    a = run_scene(scene((1, -1), 1.0, ["mceip_mu"]))["states"][0]["analyses"]["mceip_mu"]["solutions"]
    c, s = math.cos(math.radians(PHI)), math.sin(math.radians(PHI))
    at = [x for x in a if abs(x["value"] - (c * c + 1) / (c * s)) < 1e-8]
    assert sorted(tuple(x["pattern"]) for x in at) == [("slip", "stick"), ("stick", "slip")]


@pytest.mark.parametrize("signs,mu", [((1, 1), 4.0), ((-1, -1), 3.0), ((1, -1), 7.0), ((-1, 1), 4.0)])
def test_sufficient_is_the_all_slip_solution(signs, mu):
    """The sufficient condition (17)-(18) is exactly the all-slip solutions with lambda^2 > 0."""
    a = run_scene(scene(signs, mu))["states"][0]["analyses"]
    allslip = [s[0] for s in analytic_lambda2(K, M, PHI, mu, *signs) if s[2] == ["slip", "slip"] and s[0] > 0]
    assert a["sufficient"]["lambda2"] == pytest.approx(allslip, rel=1e-10)
    assert a["sufficient"]["satisfied"] == bool(allslip)


def test_mu_only_scene_builds_no_mass_matrix():
    res = run_scene(scene((1, -1), 1.0, ["mceip_mu"]))
    names = [s["name"] for s in res["stages"]]
    assert "assemble mass matrix" not in names
    assert "MCEIP-mu (21)-(23)" in names
    res = run_scene(scene((1, -1), 1.0, ["mceip_lambda2"]))
    assert "assemble mass matrix" in [s["name"] for s in res["stages"]]


def test_necessary_condition_matches_dense_symmetric_part():
    from app.systems.particles.path import particle_matrices
    mu = 2.5
    Kd, _ = particle_matrices(K, M, PHI)
    c, s = math.cos(math.radians(PHI)), math.sin(math.radians(PHI))
    for S1, S2 in ((1, 1), (1, -1), (-1, 1)):
        Ks = K * np.array([[c * c + 1 - mu * c * s * S1, -S1 * S2], [-S1 * S2, c * c + 1 + mu * c * s * S2]])
        ref = np.linalg.eigvalsh(0.5 * (Ks + Ks.T)).min()
        a = run_scene(scene((S1, S2), mu, ["necessary"]))["states"][0]["analyses"]["necessary"]
        assert a["min_eig_K_sym"] == pytest.approx(ref, rel=1e-10)
        assert a["min_eig_M_sym"] == pytest.approx(M, rel=1e-12)
        assert a["satisfied"] == (ref <= 0)
