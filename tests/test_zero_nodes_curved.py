"""Zero-reaction contact nodes (the paper's set Z) on a curved obstacle (docs/method.md section 8):
the rate conditions (9) in the frame at the node's contact point, the slip nodes' curvature
terms, the quadratic MCEIP-mu with pairs (enumeration, exact proof, branch and bound and its
checker), against closed forms and independent numpy computations."""
import copy
import itertools
import math

import numpy as np
import pytest
import scipy.linalg
from conftest import run_scene
from mpi4py import MPI

from app.analyses.mceip_mu.quadratic.bb import prove_bb
from app.analyses.mceip_mu.quadratic.check import check_log
from app.analyses.mceip_mu.quadratic.problem import enumerate_quadratic, quadratic_mu_result
from app.analyses.mceip_mu.quadratic.proof import prove_quadratic
from app.analyses.outcomes import Failed

K, M, PHI, P = 1000.0, 2.0, 35.0, 3000.0
C, S_ = math.cos(math.radians(PHI)), math.sin(math.radians(PHI))
CS = C * S_


# --- the two particles: particle 0 in impending slip (sign S1), particle 1 at zero reaction ----

def _particles(S1, obstacle, mu=1.0, analyses=("mceip_mu", "enumerate", "mceip_lambda2", "necessary")):
    """The analyses of the two-particle state with r_1 = 0, u_1 = 0 (set Z) and particle 0 slipping."""
    from app.analyses.pencils.curvature import attach
    from app.analyses.runner import analyse_state
    from app.common.stages import Stages
    from app.loading.classify import classify
    from app.loading.state import EquilibriumState
    from app.scene.schema import parse_scene
    from app.systems.particles.path import build
    sc = parse_scene({"name": "z", "mu": mu, "analyses": list(analyses), "mceip_lambda2_mu": mu,
                      "system": {"type": "two_particles", "k": K, "m": M, "phi_deg": PHI, "signs": [S1, 1],
                                 "obstacle": obstacle, "normal_reaction": P},
                      "settings": {"enumerate_max_slip": 12}})
    system = build(sc.system, MPI.COMM_WORLD, Stages())
    st = EquilibriumState(0, {}, np.zeros(2), np.zeros(2), np.array([S1 * mu * P, 0.0]), np.array([-P, 0.0]))
    cls = attach(classify(st, mu), st, system)
    try:
        return cls, analyse_state(system, cls, sc)
    finally:
        system.destroy()


def closed_form(S1, beta):
    """Every MCEIP-mu solution of the particles (units of k, beta = kappa P / k), derived by hand
    over the eleven supports of (x_T0, a, b, x_N1): with A(mu) = c^2 + 1 + beta (1 + mu^2) - mu cs S1,

    * S1 = -1, support {T0, a, N1} (particle 1 slides +T and lifts off; y_b = 0 exactly):
      w_N1 = 0 gives x_N1 = cs a / (1 + s^2), w_T1 = 0 gives x_T0 = D a, D = 2 / (1 + s^2), and
      A D = 1: beta mu^2 + cs mu + c^2 + (1 - s^2) / 2 + beta = 0;
    * S1 = +1, support {T0, b} (slides -T, stays in contact, y_N = cs b, y_a = 2 mu cs b):
      A(mu) (c^2 + 1 + mu cs) = 1, b / x_T0 = 1 / (c^2 + 1 + mu cs);

    every other support leaves a sign of (26) violated. Returns (mu, x_c) with x_c summing to 1."""
    out = []
    if S1 == -1:
        D = 2.0 / (1 + S_ * S_)
        for mu in np.roots([beta, CS, C * C + (1 - S_ * S_) / 2 + beta]):
            if abs(np.imag(mu)) < 1e-12 and np.real(mu) >= 0:
                x = np.array([D, 1.0, 0.0, CS / (1 + S_ * S_)])
                out.append((float(np.real(mu)), x / x.sum()))
    else:
        a0 = C * C + 1 + beta
        quartic = np.polysub(np.polymul([beta, -CS, a0], [CS, C * C + 1]), [1.0])
        for mu in np.roots(np.trim_zeros(quartic, "f")):
            if abs(mu.imag) < 1e-9 * max(1.0, abs(mu)) and mu.real > 0:
                x = np.array([1.0, 0.0, 1.0 / (C * C + 1 + mu.real * CS), 0.0])
                out.append((float(mu.real), x / x.sum()))
    return sorted(out, key=lambda t: t[0])


@pytest.mark.parametrize("S1, R, side", [(-1, 20.0, "outside"), (-1, 50.0, "inside"), (1, 20.0, "outside"),
                                         (1, 50.0, "inside")])
def test_two_particles_with_a_zero_node_closed_form(S1, R, side):
    """The proven MCEIP-mu list in [0, cap] and the enumeration are the closed forms: values
    (1e-10), modes (1e-8), and the zero node's motion; necessary/sufficient stay Failed. On the
    convex circle with S1 = -1 the curvature creates the instability (the line has none)."""
    beta = (-1.0 if side == "outside" else 1.0) / R * P / K
    expected = closed_form(S1, beta)
    cls, a = _particles(S1, {"type": "circle", "radius": R, "side": side})
    assert cls.status == ("slip", "zero") and cls.geometric == pytest.approx((beta * K, 0.0), rel=1e-15)
    assert isinstance(a["necessary"], Failed) and "zero-reaction" in a["necessary"].reason
    d = a["mceip_mu"]
    cap = d.certificate.interval[1]
    assert d.certified and d.complete.proven and d.complete.count == sum(1 for v, _ in expected if v <= cap)
    got = [x for x in d.solutions if x.value <= cap]
    assert len(got) == d.complete.count
    for sol, (v, x) in zip(got, expected):
        assert sol.value == pytest.approx(v, rel=1e-10)
        lo, hi = sol.evidence["enclosure"]
        assert lo - 1e-13 * v <= v <= hi + 1e-13 * v
        assert np.allclose(list(sol.evidence["x_c"].values()), x, atol=1e-8)
        zn = sol.evidence["zero_nodes"][0]
        assert (zn["tangential"], zn["normal"]) == (("slides +T", "separates") if S1 == -1 else
                                                   ("slides -T", "stays in contact"))
    enum = a["enumerate"].problems["mu"].solutions
    assert [s.value for s in enum] == pytest.approx([v for v, _ in expected], rel=1e-10)
    if S1 == -1:
        assert (len(expected) == 1) == (side == "outside")


def test_two_particles_zero_node_flat_limit():
    """R = 1e12 (the particles' scale, 1 mm): the classification and the MCEIP-mu values in
    [0, cap] (proven on both) are the straight line's to 1e-8; the line's closed form
    mu = sqrt((c^2 + 1)^2 - 1) / cs for S1 = +1."""
    for S1 in (1, -1):
        cf, flat = _particles(S1, {"type": "line"}, analyses=("mceip_mu",))
        cc, curved = _particles(S1, {"type": "circle", "radius": 1e12, "side": "outside"}, analyses=("mceip_mu",))
        assert cf.status == cc.status and cf.signs == cc.signs
        cap = flat["mceip_mu"].certificate.interval[1]
        fv = [s.value for s in flat["mceip_mu"].solutions if s.value <= cap]
        cv = [s.value for s in curved["mceip_mu"].solutions if s.value <= cap]
        assert flat["mceip_mu"].certified and curved["mceip_mu"].certified
        assert cv == pytest.approx(fv, rel=1e-8)
        assert fv == ([pytest.approx(math.sqrt((C * C + 1) ** 2 - 1) / CS, rel=1e-10)] if S1 == 1 else [])


# --- random split pencils with pairs: enumeration, brute force, proofs, checker ---------------

def random_split(seed: int, n_slip: int, n_zero: int, curvature: float = -1.0):
    """A random split pencil of ``n_slip`` slip nodes and ``n_zero`` zero-reaction nodes with the
    slip nodes' G (app/analyses/pencils/curved_split.py's construction on a random SPD Schur complement)."""
    from app.analyses.pencils.reduced import split_pencil
    from app.loading.classify import Classification
    rng = np.random.default_rng(seed)
    n = n_slip + n_zero
    B = rng.normal(size=(2 * n, 2 * n))
    Sc = B @ B.T + 0.3 * np.eye(2 * n)
    status = tuple(["slip"] * n_slip + ["zero"] * n_zero)
    signs = tuple(int(v) for v in rng.choice([-1, 1], n_slip)) + (0,) * n_zero
    cls = Classification(status, signs)
    sp = split_pencil(Sc, 2 * np.arange(n), 2 * np.arange(n) + 1, np.ones(n), np.ones(n), cls, np.array([], dtype=int))
    G = np.zeros_like(sp.A0)
    for k in range(n_slip):
        G[k, k] = curvature * rng.uniform(0.2, 1.5)
    return sp.A0 + G, sp.A1, G, [tuple(p) for p in sp.pairs]


def brute_force(A0, A1, A2, pairs, mu_max):
    """Independent: every support without a pair, QZ on the companion pencil of A(mu)[J, J],
    the null vector by SVD, sign checks x_J > 0, y off J >= 0 (1e-9 of the pencil's scale)."""
    s = A0.shape[0]
    sc = np.max(np.abs(A0))
    out = []
    for k in range(1, s + 1):
        for J in itertools.combinations(range(s), k):
            if any(a in J and b in J for a, b in pairs):
                continue
            ix = np.ix_(J, J)
            Z, I = np.zeros((k, k)), np.eye(k)
            w = scipy.linalg.eigvals(np.block([[Z, I], [-A0[ix], -A1[ix]]]), np.block([[I, Z], [Z, A2[ix]]]))
            for mu in w[np.isfinite(w)]:
                if abs(mu.imag) > 1e-7 * max(1, abs(mu)) or not -1e-12 <= mu.real <= mu_max:
                    continue
                m = max(mu.real, 0.0)
                A = A0 + m * A1 + m * m * A2
                _, sv, Vh = np.linalg.svd(A[ix])
                if sv[-1] > 1e-9 * sc * (1 + m * m):
                    continue
                v = Vh[-1] * np.sign(Vh[-1].sum())
                if np.min(v) <= 1e-9 * np.max(np.abs(v)):
                    continue
                x = np.zeros(s)
                x[list(J)] = v / v.sum()
                y = A @ x
                if all(y[i] >= -1e-9 * sc for i in range(s) if i not in J):
                    out.append((m, J))
    out.sort()
    dedup = []
    for m, J in out:
        if not any(J == J2 and abs(m - m2) <= 1e-8 * max(1, m) for m2, J2 in dedup):
            dedup.append((m, J))
    return dedup


def _support(d):
    return tuple(int(i) for i in np.flatnonzero([p == "slip" for p in d["pattern"]]))


CASES = [(seed, ns, nz, kappa) for seed, (ns, nz, kappa) in enumerate([(1, 1, -1.0), (2, 1, -1.0), (1, 2, -1.0),
                                                                      (2, 1, 0.6), (3, 1, -1.0), (2, 2, -1.0)])]


@pytest.mark.parametrize("seed, n_slip, n_zero, kappa", CASES)
def test_quadratic_enumeration_with_pairs_is_the_brute_force(seed, n_slip, n_zero, kappa):
    """enumerate_quadratic with pairs: the same (mu, support) list as the brute force over all
    supports; no support holds both halves of a pair; the columns of a pair are exact negatives."""
    A0, A1, A2, pairs = random_split(100 + seed, n_slip, n_zero, kappa)
    for a, b in pairs:
        assert all(np.array_equal(Mx[:, b], -Mx[:, a]) for Mx in (A0, A1, A2))
    got = [(d["value"], _support(d)) for d in enumerate_quadratic(A0, A1, A2, 14, mu_max=50.0, pairs=pairs)]
    ref = brute_force(A0, A1, A2, pairs, 50.0)
    assert [J for _, J in got] == [J for _, J in ref], (got, ref)
    assert [m for m, _ in got] == pytest.approx([m for m, _ in ref], rel=1e-8, abs=1e-12)
    assert not any(a in J and b in J for _, J in got for a, b in pairs)


PROVE = [(7, 2, 1, -1.0), (8, 1, 2, -1.0), (9, 3, 1, 0.6), (10, 2, 2, -1.0), (11, 3, 2, -1.0), (12, 4, 2, 0.6)]


@pytest.mark.parametrize("seed, n_slip, n_zero, kappa", PROVE)
def test_proofs_with_pairs_agree_with_the_enumeration(seed, n_slip, n_zero, kappa):
    """The exact per-support proof and the branch and bound (its log accepted by the checker),
    both with pairs: complete on [0, cap], the enumeration's list there (supports, values inside
    the enclosures); quadratic_mu_result certifies it (by the branch and bound above s = 8)."""
    cap = 20.0
    A0, A1, A2, pairs = random_split(200 + seed, n_slip, n_zero, kappa)
    found = [d for d in enumerate_quadratic(A0, A1, A2, 14, pairs=pairs) if d["value"] <= cap]
    exact = prove_quadratic(A0, A1, A2, cap, max_s=12, pairs=pairs)
    bb = prove_bb(A0, A1, A2, cap, pairs=pairs)
    assert bb.log["pairs"] == [list(p) for p in pairs]
    print(f"s = {A0.shape[0]}: {len(found)} solutions, {len(bb.log['nodes'])} nodes")
    for proof in (exact, bb):
        assert proof.proven, proof.undecided[:3]
        assert [p.support for p in proof.solutions] == [_support(d) for d in found]
        for p, d in zip(proof.solutions, found):
            assert p.enclosure[0] - 1e-10 * p.enclosure[1] <= d["value"] <= p.enclosure[1] * (1 + 1e-10)
    res = quadratic_mu_result(A0, A1, A2, cap, 14, pairs=pairs)      # above s = 8: the branch and bound
    assert res.certified and res.complete.count == len(found)
    assert res.proof["log"]["format"] == ("mceip-mu-quadratic-bb/1" if A0.shape[0] > 8 else "mceip-mu-quadratic/1")


def _pair_log():
    A0, A1, A2, pairs = random_split(211, 2, 2, -1.0)
    proof = prove_bb(A0, A1, A2, 20.0, pairs=pairs)
    assert proof.proven
    return (A0, A1, A2), pairs, proof


def test_checker_rejects_tampered_pair_closures():
    """The checker verifies the pairs on the pencil and every pair closure: a node called
    ``pair`` whose F holds none, a pair that is not two opposite columns, a forced child that
    drops an index that is not a partner, a missing pairs list (then a pair leaf is not closed)."""
    Pn, pairs, proof = _pair_log()
    assert not check_log(*Pn, proof.log).errors
    nodes = proof.log["nodes"]
    branches = [k for k, n in enumerate(nodes) if n["kind"] == "branch" and n["i"] in {i for p in pairs for i in p}]
    assert branches
    for k in [i for i, n in enumerate(nodes) if n["kind"] in ("cop", "farkas", "leaf")][:5]:
        log = copy.deepcopy(proof.log)
        log["nodes"][k]["kind"] = "pair"                         # F holds no pair: not a closure
        rep = check_log(*Pn, log)
        assert rep.errors and not rep.complete and not rep.onset_proven
    a, b = pairs[0]
    other = next(i for i in range(Pn[0].shape[0]) if i not in (a, b))
    for bad in ([[a, other]], [[a, a]], [[a, b], [b, a, 1]]):
        log = copy.deepcopy(proof.log)
        log["pairs"] = bad
        rep = check_log(*Pn, log)
        assert rep.errors and not rep.complete
    k = branches[0]
    log = copy.deepcopy(proof.log)
    forced = log["nodes"][log["nodes"][k]["children"][1]]
    keep = [j for j in forced["U"] if j not in forced["F"]]
    assert keep
    forced["U"] = [j for j in forced["U"] if j != keep[0]]      # drops an index that is no partner
    assert check_log(*Pn, log).errors
    log = copy.deepcopy(proof.log)
    del log["pairs"]                                             # the partner-dropping branches no longer cover
    assert check_log(*Pn, log).errors


# --- a real FEM scene: the block pressed on a circle until a node just touches -----------------

def _block(tmp_path, angle_deg=0.0, R=400.0):
    """The 80 x 40 block of tests/test_curved_gmsh.py on the circle of radius 400 below AB, its top
    moved by (-0.3, -d) in one step, d = 0.53960013013772 (found by regula falsi on node 7's gap and
    reaction): node 7 then touches the circle with zero reaction (set Z), node 3 slips, three nodes
    stick. ``angle_deg``: the body and the motion rotated about the circle's centre."""
    from test_curved_gmsh import write_geo
    centre = (40.0, -R)
    f = write_geo(tmp_path / f"b{angle_deg:g}.geo", angle_deg=angle_deg, about=centre)
    c, s = math.cos(math.radians(angle_deg)), math.sin(math.radians(angle_deg))
    v = (-0.3, -0.5396001301377247)
    return {"name": "z", "mu": 1.1, "analyses": ["mceip_mu", "enumerate", "mceip_lambda2", "necessary"],
            "system": {"type": "gmsh", "file": f, "contact": "AB", "prescribed": {"CD": "xy"},
                       "material": {"E": 5.0, "nu": 0.48, "density": 1.2e-9}, "thickness": 9.6,
                       "obstacle": {"type": "circle", "centre": list(centre), "radius": R, "side": "outside"},
                       "program": [{"name": "press", "steps": 1,
                                    "displacement": {"CD": {"translation": [c * v[0] - s * v[1], s * v[0] + c * v[1]]}}}]}}


@pytest.fixture(scope="module")
def block_z(tmp_path_factory):
    return run_scene(_block(tmp_path_factory.mktemp("zc")))


def test_block_on_a_circle_with_a_zero_node_is_analysed(block_z):
    """A Z state of a FEM body on a curve: MCEIP-mu proven (exact per-support proof, s = 4 with
    the pair), the enumeration and the MCEIP-lambda^2 search run, only necessary is Failed."""
    st = block_z["states"][-1]
    status = [n["status"] for n in st["nodes"]]
    assert status.count("zero") == 1 and status.count("slip") == 1 and status[7] == "zero"
    assert st["curved_contact"]["frame"][7][1] == pytest.approx(math.sin(math.atan(16.0 / 400.0)), rel=0.05)  # rotated
    a = st["analyses"]
    assert a["necessary"].get("failed") and "zero-reaction" in a["necessary"]["reason"]
    for name in ("mceip_mu", "enumerate", "mceip_lambda2"):
        assert not a[name].get("failed"), (name, a[name])
    mu = a["mceip_mu"]
    assert mu["certified"] and mu["complete"]["proven"] and mu["method"] == "condensed (quadratic)"
    assert mu["x_c_labels"] == ["T3", "a7", "b7", "N7"]
    enum = [s["value"] for s in a["enumerate"]["problems"]["mu"]["solutions"]]
    assert enum and [s["value"] for s in mu["solutions"]] == pytest.approx(enum, rel=1e-10)


def test_block_zero_node_rotation_invariance(tmp_path, block_z):
    """The body and its motion rotated by 30 degrees about the circle's centre: the same
    classification and the same MCEIP-mu and enumerated values (1e-10 relative)."""
    got = run_scene(_block(tmp_path, 30.0))
    a, b = block_z["states"][-1], got["states"][-1]
    assert [n["status"] for n in a["nodes"]] == [n["status"] for n in b["nodes"]]
    assert [n["sign"] for n in a["nodes"]] == [n["sign"] for n in b["nodes"]]
    for key in ("mceip_mu",):
        va = [s["value"] for s in a["analyses"][key]["solutions"]]
        vb = [s["value"] for s in b["analyses"][key]["solutions"]]
        assert va and vb == pytest.approx(va, rel=1e-10)
    ea = [s["value"] for s in a["analyses"]["enumerate"]["problems"]["mu"]["solutions"]]
    eb = [s["value"] for s in b["analyses"]["enumerate"]["problems"]["mu"]["solutions"]]
    assert eb == pytest.approx(ea, rel=1e-10)
    print("rotated by 30 degrees: critical mu", ea, eb)


def test_quadratic_enumeration_with_free_unknowns_and_no_mu2_is_the_linear_one():
    """With ``comp`` (free unknowns x_f, y_f = 0) and ``A2 = 0`` the quadratic enumeration is the
    linear enumeration (24)-(26) of app/analyses/enumerate.py, pairs included."""
    from app.analyses.enumerate import enumerate_mceip
    from app.analyses.pencils.reduced import split_pencil
    from app.loading.classify import Classification
    rng = np.random.default_rng(5)
    n, nf = 3, 2
    B = rng.normal(size=(2 * n + nf, 2 * n + nf))
    Kd = B @ B.T + 0.5 * np.eye(2 * n + nf)
    cls = Classification(("slip", "zero", "slip"), (1, 0, -1))
    sp = split_pencil(Kd, nf + 2 * np.arange(n), nf + 2 * np.arange(n) + 1, np.ones(n), np.ones(n), cls, np.arange(nf))
    assert len(sp.comp) == 5 and sp.pairs
    lin = enumerate_mceip(sp.A0, sp.A1, sp.comp, 12, pairs=sp.pairs)
    quad = enumerate_quadratic(sp.A0, sp.A1, np.zeros_like(sp.A0), 12, comp=sp.comp, pairs=sp.pairs)
    assert lin and [d["pattern"] for d in quad] == [d["pattern"] for d in lin]
    assert [d["value"] for d in quad] == pytest.approx([d["value"] for d in lin], rel=1e-9)
    for q, l_ in zip(quad, lin):
        assert np.allclose(q["x_Ts"], l_["x_Ts"], atol=1e-8)


def _particles_lambda2_by_hand(S1, beta, mu):
    """``(A0, A1)`` of MCEIP-lambda^2 of the particles (units of k, t = lambda^2 m / k) written
    from the rates by hand: over (x_T0, a, b, x_N1),
    y0 = (c^2 + 1 + t + beta (1 + mu^2) - mu cs S1) x + S1 (a - b),
    w_T1 = S1 x + (c^2 + 1 + t)(a - b) - cs x_N1,  w_N1 = cs (a - b) - (s^2 + 1 + t) x_N1,
    y_a = w_T1 - mu w_N1, y_b = -w_T1 - mu w_N1, y_N = -w_N1."""
    def rows(t):
        A = C * C + 1 + t + beta * (1 + mu * mu) - mu * CS * S1
        wT = np.array([S1, C * C + 1 + t, -(C * C + 1 + t), -CS])
        wN = np.array([0.0, CS, -CS, -(S_ * S_ + 1 + t)])
        return np.array([[A, S1, -S1, 0.0], wT - mu * wN, -wT - mu * wN, -wN])
    A0 = rows(0.0)
    return A0, rows(1.0) - A0


@pytest.mark.parametrize("S1, mu, count", [(1, 4.0, 1), (-1, 6.0, 1), (-1, 4.0, 0), (1, 1.0, 0)])
def test_two_particles_zero_node_lambda2(S1, mu, count):
    """MCEIP-lambda^2 at mu on the convex circle R = 20: the enumeration equals the brute force on
    the pencil written by hand (lambda^2 = t k / m, 1e-9); the search finds these solutions
    (S1 = +1: particle 1 slides -T in contact; S1 = -1: it slides +T and lifts off) and no other."""
    beta = -1.0 / 20.0 * P / K
    A0, A1 = _particles_lambda2_by_hand(S1, beta, mu)
    ref = [(t * K / M, J) for t, J in brute_force(A0, A1, np.zeros((4, 4)), [(1, 2)], 1e4)]
    _, a = _particles(S1, {"type": "circle", "radius": 20.0, "side": "outside"}, mu=mu,
                      analyses=("mceip_lambda2", "enumerate"))
    got = a["enumerate"].problems["lambda2"].solutions
    assert [v for v, _ in ref] == pytest.approx([s.value for s in got], rel=1e-9)
    assert [J for _, J in ref] == [tuple(int(i) for i, x in enumerate(s.evidence["x_c"].values()) if x > 1e-12)
                                   for s in got]
    assert len(ref) == count
    assert [s.value for s in a["mceip_lambda2"].solutions] == pytest.approx([v for v, _ in ref], rel=1e-8)


def test_stored_proof_of_a_zero_node_state_is_rechecked(tmp_path):
    """``app run`` stores the quadratic proof with its pairs and ``app check`` proves it again;
    without the pairs (or with a pair that is not two opposite columns) the stored pencil is not
    proven: the supports holding both halves have ``det A_JJ = 0`` identically."""
    import io
    import json

    import yaml
    from conftest import run_cli_here

    from app.io.check import check_folder
    sc = _block(tmp_path)
    sc["system"]["file"] = "b0.geo"                     # written by _block, relative to the scene
    sc["analyses"] = ["mceip_mu"]
    (tmp_path / "z.yaml").write_text(yaml.safe_dump(sc))
    assert run_cli_here("run", str(tmp_path / "z.yaml"), "-o", str(tmp_path / "out"), "-q", cwd=tmp_path).returncode == 0
    checks = [c for c in check_folder(tmp_path / "out").states if c.s]
    assert checks and all(c.ok and c.s == 4 for c in checks)
    assert any(v.startswith("complete list") for v in checks[0].verified)
    path = next((tmp_path / "out" / "proofs").glob("*.npz"))
    with np.load(path) as z:
        arrays = {k: z[k] for k in z.files}
    log = json.loads(str(arrays["log"]))
    assert log["pairs"] == [[1, 2]]
    for bad in ([], [[1, 3]]):
        buf = io.BytesIO()
        np.savez(buf, **{**arrays, "log": np.array(json.dumps({**log, "pairs": bad}))})
        path.write_bytes(buf.getvalue())
        checks = [c for c in check_folder(tmp_path / "out").states if c.s]
        assert not checks[0].ok and any("pairs" in f for f in checks[0].failed), bad


def _tilted(tmp_path, obstacle):
    """The 80 x 40 block tilted by 1 degree about A (which touches the obstacle first), its top
    moved by (1, -d) in one step, d = 0.5314372743421658 (found by regula falsi on node 3's gap):
    nodes 0-2 slip, node 3 touches with zero reaction (set Z)."""
    from test_curved_gmsh import write_geo
    f = write_geo(tmp_path / "t.geo", angle_deg=1.0, about=(0.0, 0.0))
    return {"name": "z", "mu": 1.1, "analyses": ["mceip_mu", "enumerate"],
            "system": {"type": "gmsh", "file": f, "contact": "AB", "prescribed": {"CD": "xy"},
                       "material": {"E": 5.0, "nu": 0.48, "density": 1.2e-9}, "thickness": 9.6, "obstacle": obstacle,
                       "program": [{"name": "press", "steps": 1,
                                    "displacement": {"CD": {"translation": [1.0, -0.5314372743421658]}}}]}}


def test_block_zero_node_flat_limit(tmp_path):
    """The tilted block's Z state on the line and on a circle of radius R = 1e12 L tangent to it at
    A: the same classification and the same MCEIP-mu values (1e-8 relative), proven on both (the
    linear engine with pairs on the line, the quadratic exact proof with pairs on the circle)."""
    R = 1e12 * 80.0
    flat = run_scene(_tilted(tmp_path, {"type": "line"}))["states"][-1]
    curved = run_scene(_tilted(tmp_path, {"type": "circle", "centre": [0.0, -R], "radius": R, "side": "outside"}))
    curved = curved["states"][-1]
    assert [n["status"] for n in flat["nodes"]][:5] == ["slip", "slip", "slip", "zero", "free"]
    assert [n["status"] for n in curved["nodes"]] == [n["status"] for n in flat["nodes"]]
    assert [n["sign"] for n in curved["nodes"]] == [n["sign"] for n in flat["nodes"]]
    a, b = flat["analyses"]["mceip_mu"], curved["analyses"]["mceip_mu"]
    assert a["certified"] and b["certified"] and a["method"] == "condensed" and b["method"] == "condensed (quadratic)"
    cap = a["certificate"]["interval"][1]
    va = [s["value"] for s in a["solutions"] if s["value"] <= cap]
    vb = [s["value"] for s in b["solutions"] if s["value"] <= cap]
    assert va and vb == pytest.approx(va, rel=1e-8)
    ea = [s["value"] for s in flat["analyses"]["enumerate"]["problems"]["mu"]["solutions"]]
    eb = [s["value"] for s in curved["analyses"]["enumerate"]["problems"]["mu"]["solutions"]]
    assert eb[:len(ea)] == pytest.approx(ea, rel=1e-8)
    print("flat limit: critical mu", va, vb, "largest relative difference", max(abs(x - y) / x for x, y in zip(va, vb)))


def test_the_zero_node_state_on_a_gmsh_curve(tmp_path, block_z):
    """The same Z state with the circle given as an arc of the Gmsh file (``type: curve``, the
    interpolated curve of app/loading/curve.py): the same statuses, MCEIP-mu proven the same, the
    value above the cap to 1e-9 relative."""
    import json
    import pathlib

    from test_curve_obstacle import ARC
    scene = _block(tmp_path)
    (tmp_path / "c.geo").write_text(pathlib.Path(scene["system"]["file"]).read_text() + ARC.format(R=400.0))
    scene = json.loads(json.dumps(scene))
    scene["system"]["file"] = str(tmp_path / "c.geo")
    scene["system"]["obstacle"] = {"type": "curve", "physical": "ob", "side": "left"}
    a, b = block_z["states"][-1], run_scene(scene)["states"][-1]
    assert [n["status"] for n in b["nodes"]] == [n["status"] for n in a["nodes"]] and "zero" in [n["status"] for n in b["nodes"]]
    ma, mb = a["analyses"]["mceip_mu"], b["analyses"]["mceip_mu"]
    assert mb["certified"] and mb["complete"]["proven"] and mb["complete"]["count"] == ma["complete"]["count"]
    va, vb = ([s["value"] for s in m["solutions"]] for m in (ma, mb))
    assert va and vb == pytest.approx(va, rel=1e-9)
