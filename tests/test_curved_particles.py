"""Curved rigid obstacles, hand-solved cases (docs/method.md section 8).

1. A single particle on a circle: the critical friction coefficients from the exact nonlinear
   equilibrium (finite differences of the residual along the circle, no rate formula used),
   against the app's quadratic pencil K*(mu) = K0 + G + mu K1 + mu^2 G.
2. The paper's two-particle system (Table 1) on a circle of radius R: in units of k, with
   beta = kappa P / k (kappa = -1/R outside, +1/R inside) and a(mu) = c^2 + 1 + beta (1 + mu^2),

       [[L + a(mu) - mu cs S1, -sigma], [-sigma, L + a(mu) + mu cs S2]] x = y,  0 <= x ⊥ y >= 0,

   slip-stick: a(mu) - mu cs S1 = 0 (sigma = -1): beta mu^2 - cs S1 mu + c^2 + 1 + beta = 0,
   stick-slip: a(mu) + mu cs S2 = 0 (sigma = -1); slip-slip: (a - mu cs S1)(a + mu cs S2) = 1 with
   x2 / x1 = sigma (a - mu cs S1) > 0 (a quartic in mu; for S1 = S2 a quadratic in mu^2).
3. R -> infinity: the flat results, with the observed rate of convergence.
"""
import math

import numpy as np
import pytest
from conftest import run_scene

K, M, PHI, P = 1000.0, 2.0, 35.0, 3000.0
C, S_ = math.cos(math.radians(PHI)), math.sin(math.radians(PHI))
CS = C * S_


def beta(R, side):
    return (-1.0 if side == "outside" else 1.0) / R * P / K


def scene(signs, mu, R=None, side=None, analyses=("mceip_lambda2", "mceip_mu", "enumerate", "sufficient", "necessary")):
    ob = {"type": "line"} if R is None else {"type": "circle", "radius": R, "side": side}
    return {"name": "tp", "system": {"type": "two_particles", "k": K, "m": M, "phi_deg": PHI, "signs": list(signs),
                                     "obstacle": ob, "normal_reaction": P},
            "mu": mu, "analyses": list(analyses)}


def analytic_mu(b, S1, S2):
    """All MCEIP-mu solutions of the two particles on the circle (closed forms above)."""
    sig = S1 * S2
    c0 = C * C + 1 + b
    sols = []
    if sig == -1:
        for coeffs, x, pat in (([b, -CS * S1, c0], (1.0, 0.0), ["slip", "stick"]),
                               ([b, CS * S2, c0], (0.0, 1.0), ["stick", "slip"])):
            for mu in np.roots(coeffs):
                if abs(mu.imag) < 1e-12 and mu.real >= 0:
                    sols.append((mu.real, x, pat))
    quartic = np.polysub(np.polymul([b, -CS * S1, c0], [b, CS * S2, c0]), [1.0])
    for mu in np.roots(np.trim_zeros(quartic, "f")):
        if abs(mu.imag) > 1e-9 * max(1, abs(mu)) or mu.real < 0:
            continue
        mu = mu.real
        ratio = sig * (c0 + b * mu * mu - mu * CS * S1)
        if ratio > 0:
            sols.append((mu, (1 / (1 + ratio), ratio / (1 + ratio)), ["slip", "slip"]))
    return sorted(sols, key=lambda t: (t[0], t[2]))


def analytic_lambda2(b, mu, S1, S2):
    """All MCEIP-lambda^2 solutions at mu (lambda^2 = L k / m)."""
    a, sig = C * C + 1 + b * (1 + mu * mu), S1 * S2
    bb = mu * CS
    sols = []
    if sig == -1:
        for L, x, pat in ((bb * S1 - a, (1.0, 0.0), ["slip", "stick"]), (-a - bb * S2, (0.0, 1.0), ["stick", "slip"])):
            if L >= 0:
                sols.append((L * K / M, x, pat))
    for Pp in np.roots([1.0, bb * S2 - bb * S1, -bb * bb * S1 * S2 - 1.0]):
        if abs(Pp.imag) > 1e-12:
            continue
        ratio, L = sig * (Pp.real - bb * S1), Pp.real - a
        if ratio > 0 and L >= 0:
            sols.append((L * K / M, (1 / (1 + ratio), ratio / (1 + ratio)), ["slip", "slip"]))
    return sorted(sols, key=lambda t: (t[0], t[2]))


def assert_same_set(found, expected, rel=1e-8):
    found = sorted(found, key=lambda s: (s["value"], s["pattern"]))
    assert len(found) == len(expected), (found, expected)
    for f, (v, x, pat) in zip(found, expected):
        assert f["value"] == pytest.approx(v, rel=rel, abs=1e-12)
        assert f["pattern"] == pat
        assert np.allclose(f["x_Ts"], x, atol=1e-8)


SIGNS = [(1, 1), (-1, -1), (-1, 1), (1, -1)]


@pytest.mark.parametrize("side", ["outside", "inside"])
@pytest.mark.parametrize("R", [20.0, 80.0, 400.0])
@pytest.mark.parametrize("signs", SIGNS)
def test_two_particles_mu_on_a_circle(signs, R, side):
    expected = analytic_mu(beta(R, side), *signs)
    a = run_scene(scene(signs, 1.0, R, side, ["mceip_mu", "enumerate"]))["states"][0]["analyses"]
    assert_same_set(a["mceip_mu"]["solutions"], expected)
    assert_same_set(a["enumerate"]["problems"]["mu"]["solutions"], expected)
    # the exact proof (app/analyses/mceip_mu/quadratic/proof.py): complete on [0, cap], every
    # closed-form value inside its rigorous enclosure (widened by the closed form's own rounding)
    d = a["mceip_mu"]
    assert d["certified"] is True and d["complete"]["proven"]
    cap = d["certificate"]["cap"]
    assert d["complete"]["count"] == sum(1 for v, _, _ in expected if v <= cap)
    for sol, (v, _, _) in zip(sorted(d["solutions"], key=lambda x: (x["value"], x["pattern"])), expected):
        if v <= cap:
            lo, hi = sol["enclosure"]
            assert sol["certified"] and lo - 1e-13 * v <= v <= hi + 1e-13 * v and hi - lo <= 1e-12 * v
    if expected and expected[0][0] <= cap:
        lo, hi = d["onset"]["enclosure"]
        assert lo - 1e-13 * expected[0][0] <= expected[0][0] <= hi + 1e-13 * expected[0][0]


def test_closed_form_same_signs():
    """S1 = S2: a(mu) = sqrt(1 + mu^2 c^2 s^2), so t = mu^2 solves
    beta^2 t^2 + (2 beta (c^2 + 1 + beta) - c^2 s^2) t + (c^2 + 1 + beta)^2 - 1 = 0."""
    for R, side in ((30.0, "outside"), (200.0, "outside"), (200.0, "inside")):
        b = beta(R, side)
        c0 = C * C + 1 + b
        A, B, Cq = b * b, 2 * b * c0 - CS * CS, c0 * c0 - 1
        ts = [(-B + sg * math.sqrt(B * B - 4 * A * Cq)) / (2 * A) for sg in (1, -1)]
        mus = sorted(math.sqrt(t) for t in ts if t >= 0 and c0 + b * t > 0 and c0 + b * t - math.sqrt(t) * CS > 0)
        for S in (1, -1):
            a = run_scene(scene((S, S), 1.0, R, side, ["mceip_mu"]))["states"][0]["analyses"]["mceip_mu"]
            assert [x["value"] for x in a["solutions"]] == pytest.approx(mus, rel=1e-10)
    # convex lowers the flat onset sqrt(c^2 + 2) / s, concave raises it
    flat = math.sqrt(C * C + 2) / S_
    out = run_scene(scene((1, 1), 1.0, 100.0, "outside", ["mceip_mu"]))["states"][0]["analyses"]["mceip_mu"]
    ins = run_scene(scene((1, 1), 1.0, 100.0, "inside", ["mceip_mu"]))["states"][0]["analyses"]["mceip_mu"]
    assert out["solutions"][0]["value"] < flat < ins["solutions"][0]["value"]


@pytest.mark.parametrize("side", ["outside", "inside"])
@pytest.mark.parametrize("signs,mu", [((1, 1), 4.0), ((-1, -1), 4.0), ((1, -1), 4.5), ((1, -1), 7.0), ((-1, 1), 4.0)])
def test_two_particles_lambda2_on_a_circle(signs, mu, side):
    expected = analytic_lambda2(beta(50.0, side), mu, *signs)
    a = run_scene(scene(signs, mu, 50.0, side))["states"][0]["analyses"]
    assert_same_set(a["mceip_lambda2"]["solutions"], expected)
    assert_same_set(a["enumerate"]["problems"]["lambda2"]["solutions"], expected)
    allslip = [x[0] for x in expected if x[2] == ["slip", "slip"] and x[0] > 0]
    assert a["sufficient"]["lambda2"] == pytest.approx(allslip, rel=1e-10)
    # the necessary condition (19): the symmetric part of K*(mu) with the curvature terms
    S1, S2 = signs
    g = beta(50.0, side) * K * (1 + mu * mu)
    Ks = K * np.array([[C * C + 1 - mu * CS * S1, -S1 * S2], [-S1 * S2, C * C + 1 + mu * CS * S2]]) + g * np.eye(2)
    ref = np.linalg.eigvalsh(0.5 * (Ks + Ks.T)).min()
    assert a["necessary"]["min_eig_K_sym"] == pytest.approx(ref, rel=1e-10)


def test_line_obstacle_is_the_default_bit_for_bit():
    """``obstacle: {type: line}`` and any normal_reaction give exactly the results without the keys."""
    base = {"name": "tp", "system": {"type": "two_particles", "k": K, "m": M, "phi_deg": PHI, "signs": [1, -1]},
            "mu": 4.5, "analyses": ["mceip_mu", "enumerate", "necessary", "sufficient"]}
    ref = run_scene(base)["states"][0]
    for extra in ({"obstacle": {"type": "line"}}, {"obstacle": {"type": "line"}, "normal_reaction": 1.0}):
        got = run_scene({**base, "system": {**base["system"], **extra}})["states"][0]
        assert got["nodes"] == ref["nodes"]
        for name in ("enumerate", "necessary", "sufficient"):
            assert got["analyses"][name] == ref["analyses"][name]
        assert [s["value"] for s in got["analyses"]["mceip_mu"]["solutions"]] == \
            [s["value"] for s in ref["analyses"]["mceip_mu"]["solutions"]]


def test_flat_limit_and_rate():
    """R -> infinity converges to the flat critical values; R = 1e12 (x the particles' scale, 1 mm)
    equals the flat obstacle to 1e-8; the observed rate is 1 (the curvature terms are O(1/R))."""
    for signs in ((1, 1), (1, -1)):
        flat = [s["value"] for s in run_scene(scene(signs, 1.0, None, None, ["mceip_mu"]))
                ["states"][0]["analyses"]["mceip_mu"]["solutions"]]
        errs = []
        Rs = [1e3, 1e4, 1e5, 1e12]
        for R in Rs:
            got = [s["value"] for s in run_scene(scene(signs, 1.0, R, "outside", ["mceip_mu"]))
                   ["states"][0]["analyses"]["mceip_mu"]["solutions"]][:len(flat)]
            errs.append(max(abs(g - f) / f for g, f in zip(got, flat)))
        rates = [math.log(errs[i] / errs[i + 1]) / math.log(Rs[i + 1] / Rs[i]) for i in range(2)]
        print(f"signs {signs}: relative error {errs}, observed rate in 1/R {rates}")
        assert errs[-1] < 1e-8
        assert all(abs(r - 1) < 0.05 for r in rates)


# --- a single particle on a circle, from the exact nonlinear equilibrium ---------------------

def _frame(theta, side):
    e = np.array([math.cos(theta), math.sin(theta)])
    n = -e if side == "outside" else e          # the body's outward normal points into the obstacle
    return np.array([-n[1], n[0]]), n           # t = (-n_y, n_x)


def _critical_mu_by_finite_differences(Kg, R, side, theta0, P0, S, mus):
    """Roots in mu of det dRes/d(theta, r_N): Res = -Kg (x(theta) - a) + r_N n(theta) + r_T t(theta),
    x(theta) = centre + R e(theta), r_T = -mu S r_N (slip continues); finite differences only."""
    def res(theta, rN, mu):
        t, n = _frame(theta, side)
        x = 7.0 + R * np.array([math.cos(theta), math.sin(theta)])
        return -Kg @ x + rN * n + (-mu * S * rN) * t

    def det(mu):
        h, hr = 1e-6, 1e-6 * P0
        d_th = (res(theta0 + h, -P0, mu) - res(theta0 - h, -P0, mu)) / (2 * h)
        d_r = (res(theta0, -P0 + hr, mu) - res(theta0, -P0 - hr, mu)) / (2 * hr)
        return np.linalg.det(np.column_stack([d_th, d_r]))

    from scipy.optimize import brentq
    vals = [det(m) for m in mus]
    return [brentq(det, mus[i], mus[i + 1], xtol=1e-14) for i in range(len(mus) - 1) if vals[i] * vals[i + 1] < 0]


@pytest.mark.parametrize("side", ["outside", "inside"])
@pytest.mark.parametrize("S", [1, -1])
def test_single_particle_on_a_circle(side, S):
    from app.analyses.mceip_mu.quadratic.problem import enumerate_quadratic
    from app.analyses.pencils.curvature import CurvedClassification, condensed_quadratic
    rng = np.random.default_rng(3 if side == "outside" else 4)
    A = rng.normal(size=(2, 2))
    Kg = A @ A.T + 0.5 * np.eye(2)                     # springs in global x/y
    R, theta0, P0 = (2.0 if side == "outside" else 20.0), 0.7, 0.9
    t, n = _frame(theta0, side)
    Q = np.column_stack([t, n])
    Kl = Q.T @ Kg @ Q                                   # paper axes (T, N) at the contact point
    kappa = (-1.0 if side == "outside" else 1.0) / R
    cls = CurvedClassification(("slip",), (S,), (kappa * P0,), ((1.0, 0.0, 0.0, 1.0),))
    A0, A1, A2 = condensed_quadratic(Kl, cls)
    # the 1-node closed form: K_TT + kappa P + mu S K_NT + mu^2 kappa P = 0
    assert A0[0, 0] == pytest.approx(Kl[0, 0] + kappa * P0) and A1[0, 0] == pytest.approx(S * Kl[1, 0])
    assert A2[0, 0] == pytest.approx(kappa * P0)
    app = sorted(s["value"] for s in enumerate_quadratic(A0, A1, A2, 4))
    fd = _critical_mu_by_finite_differences(Kg, R, side, theta0, P0, S, np.linspace(0, 60, 6001))
    roots = np.roots([kappa * P0, S * Kl[1, 0], Kl[0, 0] + kappa * P0])
    closed = sorted(r.real for r in roots if abs(r.imag) < 1e-12 and r.real >= 0)
    assert app == pytest.approx(closed, rel=1e-10)
    assert fd == pytest.approx([c for c in closed if c < 60], rel=1e-6)
    # the data exercise the cases: one root outside (either S), none or two inside
    assert len(closed) == (1 if side == "outside" else 0 if S == 1 else 2)


@pytest.mark.parametrize("ob,msg", [
    ({"type": "circle"}, "system.obstacle.radius = None: missing: a circle needs radius"),
    ({"type": "circle", "radius": 2}, "system.obstacle.side = None: missing: a circle needs side"),
    ({"type": "circle", "radius": -2, "side": "outside"}, "system.obstacle.radius = -2: Input should be greater than 0"),
    ({"type": "line", "radius": 3}, "system.obstacle.radius = 3.0: allowed only with type: circle"),
    ({"type": "ellipse"}, "system.obstacle.type = 'ellipse': Input should be 'line' or 'circle'"),
    ({"type": "circle", "radius": 2, "side": "above"}, "system.obstacle.side = 'above': Input should be 'outside' or 'inside'"),
])
def test_obstacle_keys_are_validated(ob, msg):
    from app.common.validation import SceneError
    from app.scene.schema import parse_scene
    data = scene((1, -1), 1.0)
    data["system"]["obstacle"] = ob
    with pytest.raises(SceneError) as err:
        parse_scene(data)
    assert msg in str(err.value) and "\n" not in str(err.value)
