"""Proven MCEIP-mu (app/analyses/mceip_mu) against closed forms and exhaustive enumeration.

Soundness: a claim labelled proven must agree with the floating-point enumeration of every
support (the random pencils here have well-separated solutions; the soundness benchmark covers
the near-degenerate ones with exact arithmetic). Completeness is asserted where it is cheap: the
onset always, the full list for small pencils. The checker must reject tampered logs.
"""
import copy
import json

import numpy as np
import pytest
from conftest import minimal_study
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st
from mpi4py import MPI

from app import mceip_mu
from app.analyses.enumerate import enumerate_patterns
from app.analyses.mceip_mu.kernel import checker, closing, prooflog, rounding
from app.analyses.pencils.reduced import condensed_mu_pencil, split_pencils
from app.common.stages import Stages
from app.loading.classify import classify
from app.systems.discrete import random_contact_problem


def _random_pencil(seed, n_slip, n_stick, n_free, n_int, mu):
    rng = np.random.default_rng(seed)
    system, state = random_contact_problem(rng, n_slip + n_stick + n_free, n_int, n_slip, n_stick, mu,
                                           MPI.COMM_WORLD, Stages())
    A0, A1 = condensed_mu_pencil(system.contact_schur(), classify(state, mu))
    system.destroy()
    return A0, A1


def _pd_plus_pencil(rng, s, a1_scale=3.0):
    """``A0 = B B^T + s I`` (positive definite), ``A1`` a random ``s x s`` times ``a1_scale``."""
    B = rng.normal(size=(s, s))
    return B @ B.T + s * np.eye(s), a1_scale * rng.normal(size=(s, s))


def _agrees(r, A0, A1, cap, pairs=None):
    """Every proven claim of ``r`` agrees with enumeration; returns the enumerated values."""
    ref = enumerate_patterns(A0, A1, np.arange(A0.shape[0]), t_max=cap, pairs=pairs)
    vals = [p.value for p in ref]
    if r.onset.proven:
        if vals:
            assert r.onset.value == pytest.approx(vals[0], rel=1e-7)
            assert r.onset.enclosure[0] <= vals[0] * (1 + 1e-12) and vals[0] <= r.onset.enclosure[1] * (1 + 1e-12)
        else:
            assert r.onset.value is None
    if r.all.proven:
        assert r.all.values == pytest.approx(vals, rel=1e-7)
        got = sorted((round(p.value, 7), tuple(p.support)) for p in r.solutions if p.proven)
        assert got == sorted((round(p.value, 7), tuple(p.support)) for p in ref)
    for lb_sol in vals:                    # the proven lower bound is a lower bound
        assert lb_sol >= r.lower_bound
    return vals


def test_closed_form_two_by_two():
    """A0 = I, A1 = [[-1, .2], [.1, -.5]]: support {0} at mu = 1 (y_1 = 0.1), {1} at mu = 2
    (y_0 = 0.4), {0, 1} at the positive root of 1 - 1.5 mu + 0.48 mu^2 (the other root has a
    mixed-sign mode): three critical values, each proven."""
    A0, A1 = np.eye(2), np.array([[-1.0, 0.2], [0.1, -0.5]])
    r = mceip_mu(A0, A1, cap=10.0)
    root = (1.5 + np.sqrt(1.5 ** 2 - 4 * 0.48)) / (2 * 0.48)
    assert r.certified and r.onset.proven and r.all.proven
    assert r.all.values == pytest.approx([1.0, 2.0, root], rel=1e-12)
    assert r.onset.enclosure[0] <= 1.0 <= r.onset.enclosure[1]
    for p, v in zip(sorted(r.solutions, key=lambda q: q.value), [1.0, 2.0, root]):
        assert p.enclosure[0] <= v <= p.enclosure[1]


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.integers(0, 2**31 - 1), st.integers(1, 7), st.integers(0, 2), st.integers(0, 2), st.integers(0, 4),
       st.floats(0.3, 4.0), st.floats(2.0, 60.0))
# SCIP declared this one "proven, no solution" (issue 18): the solution mu = 4.733117 on {node 1}
@example(seed=394604, n_slip=4, n_stick=2, n_free=1, n_int=1, mu=1.0, cap=8.5)
def test_proven_claims_equal_enumeration(seed, n_slip, n_stick, n_free, n_int, mu, cap):
    A0, A1 = _random_pencil(seed, n_slip, n_stick, n_free, n_int, mu)
    r = mceip_mu(A0, A1, cap)
    _agrees(r, A0, A1, cap)
    assert r.onset.proven, r.onset.status
    if A0.shape[0] <= 4:
        assert r.all.proven, r.all.status


def test_seed_394604_lists_its_solution():
    """The regression of issue 18: the solution 4.733117 (slip support {0}) is listed and proven."""
    A0, A1 = _random_pencil(394604, 4, 2, 1, 1, 1.0)
    r = mceip_mu(A0, A1, 8.5)
    assert r.onset.proven and r.onset.value == pytest.approx(4.733117, abs=1e-6)
    sol = [p for p in r.solutions if abs(p.value - 4.733117) < 1e-6]
    assert sol and sol[0].support.tolist() == [True, False, False, False]


@pytest.mark.parametrize("seed", range(4))
def test_zero_node_pairs(seed):
    rng = np.random.default_rng(seed)
    mu = 2.0
    system, state = random_contact_problem(rng, 6, 5, 3, 1, mu, MPI.COMM_WORLD, Stages())
    free = [i for i in range(len(state.r_N)) if state.r_N[i] == 0][:1]
    state.u_N[free] = 0.0
    cls = classify(state, mu)
    assert cls.counts()["zero"] == 1
    sp = split_pencils(system, cls)
    system.destroy()
    r = mceip_mu(sp.A0, sp.A1, 50.0, pairs=sp.pairs)
    _agrees(r, sp.A0, sp.A1, 50.0, pairs=sp.pairs)


def test_dense_random_pencils():
    rng = np.random.default_rng(5)
    for _ in range(6):
        s = int(rng.integers(2, 7))
        A0, A1 = _pd_plus_pencil(rng, s)
        cap = float(rng.uniform(2, 30))
        r = mceip_mu(A0, A1, cap)
        _agrees(r, A0, A1, cap)
        assert r.onset.proven


def test_no_solution_proven_by_the_sign_argument():
    A0 = np.eye(4)
    A1 = np.array([[0, 1, 0, 0], [-1, 0, 0, 0], [0, 0, 0, 1], [0, 0, -1, 0]], dtype=float)
    r = mceip_mu(A0, A1, 100.0)
    assert r.certified and r.onset.value is None and not r.all.values
    assert r.nodes == 1 and r.log.nodes[0].kind == "cop"


def test_budget_turns_into_not_proven():
    """A node budget too small for the proof: "not proven" (with what is proven), not a time limit."""
    A0, A1 = _pd_plus_pencil(np.random.default_rng(4), 30)
    r = mceip_mu(A0, A1, 1e4, onset_nodes=1)
    assert not r.certified and not r.all.proven and not r.timed_out
    assert r.all.status.startswith(("not proven", "ill-conditioned"))


def test_safety_stop_says_stopped_by_the_time_limit():
    """The wall-clock safety stop (``seconds``) is no budget: what it ends says so."""
    A0, A1 = _pd_plus_pencil(np.random.default_rng(4), 30)
    r = mceip_mu(A0, A1, 1e4, seconds=0.0)
    assert not r.certified and not r.all.proven and r.timed_out
    assert r.all.status.startswith("stopped by the time limit")


def test_scale_invariance():
    """Units: scaling the pencil (by 1e6, and by 2^-40) changes neither claims nor values."""
    A0, A1 = _pd_plus_pencil(np.random.default_rng(7), 5)
    a = mceip_mu(A0, A1, 30.0)
    for f in (1e6, 2.0 ** -40):
        b = mceip_mu(f * A0, f * A1, 30.0)
        assert (a.onset.proven, a.all.proven) == (b.onset.proven, b.all.proven)
        assert b.all.values == pytest.approx(a.all.values, rel=1e-9)


def _log_of(r) -> dict:
    return json.loads(json.dumps(r.log.to_json()))


def test_checker_accepts_the_log_and_rejects_tampering():
    """Change one witness (a diagonal scaling, a window's mu, a child link, a support): the
    checker, run from the pencil alone, must reject the claim it supported."""
    A0, A1 = _random_pencil(394604, 4, 2, 1, 1, 1.0)
    r = mceip_mu(A0, A1, 8.5)
    good = _log_of(r)
    rep = checker.check_log(A0, A1, prooflog.ProofLog.from_json(good))
    assert rep.onset_ok and rep.all_ok and len(rep.solutions) == len(r.all.values)

    def rejected(edit) -> bool:
        bad = copy.deepcopy(good)
        edit(bad)
        rep = checker.check_log(A0, A1, prooflog.ProofLog.from_json(bad))
        return not (rep.onset_ok and rep.all_ok)

    cops = [n for n in good["nodes"] if n["kind"] == "cop" and any(v != 1.0 for v in n["d"])] or \
        [n for n in good["nodes"] if n["kind"] == "cop"]
    wins = [n for n in good["nodes"] if n.get("windows")]
    branches = [n for n in good["nodes"] if n["kind"] == "branch"]
    farkas = [n for n in good["nodes"] if n["kind"] == "farkas" and len(n.get("F", [])) < len(n["U"])]
    assert cops and wins and branches and farkas

    def widen_cop(log):                 # a closed node claims a much wider interval
        for n in log["nodes"]:
            if n["id"] == cops[0]["id"]:
                n["b"] = 1e6

    def move_window(log):               # a window moved off its eigenvalue
        for n in log["nodes"]:
            if n["id"] == wins[0]["id"]:
                n["windows"][0]["mu"] *= 1.01

    def cut_child(log):                 # a branch node loses a child
        for n in log["nodes"]:
            if n["id"] == branches[0]["id"]:
                n["children"] = n["children"][:-1]

    def force_more(log):                # a branch child claims a larger forced set than it may
        kid = branches[0]["children"][0]
        for n in log["nodes"]:
            if n["id"] == kid:
                n["F"] = sorted(set(n.get("F", [])) | set(n["U"][:1]))

    def farkas_sign(log):               # a Farkas vector positive off the forced set
        for n in log["nodes"]:
            if n["id"] == farkas[0]["id"]:
                i = next(j for j in range(len(n["w"])) if j not in n.get("F", []))
                n["w"][i] = abs(n["w"][i]) + 1.0

    def family_as_leaf(log):            # a family closed as if it were one exact support
        for n in log["nodes"]:
            if n["id"] == farkas[0]["id"]:
                n["kind"], n["windows"], n["pieces"] = "leaf", [], []

    def shrink_root_support(log):       # the root no longer holds every support
        for n in log["nodes"]:
            if n["id"] in log["all_roots"]:
                n["U"] = n["U"][:-1]

    def drop_solution_window(log):      # the listed solution's window removed
        for n in log["nodes"]:
            if n.get("windows"):
                n["windows"] = []

    for edit in (widen_cop, move_window, cut_child, force_more, farkas_sign, family_as_leaf,
                 shrink_root_support, drop_solution_window):
        assert rejected(edit), edit.__name__


def test_verified_pd_refuses_a_matrix_just_below_definite():
    """The shifted Cholesky proves PD only with a margin above its rounding bound."""
    rng = np.random.default_rng(0)
    B = rng.normal(size=(40, 40))
    H = B @ B.T
    lam = np.linalg.eigvalsh(H)[0]
    assert rounding.verified_pd(H - 0.999 * lam * np.eye(40))
    assert not rounding.verified_pd(H - 1.000001 * lam * np.eye(40))
    assert not rounding.verified_pd(H, radius=lam * 1.01)


@pytest.mark.slow
@pytest.mark.parametrize("pattern", ["crossed", "left"])
def test_block_states_onset_proven(pattern):
    """Every distinct classification of a 12 x 6 block path: the onset and the complete list
    proven, and equal to enumeration's values below the cap."""
    from benchmarks.problems import block_problems
    probs = block_problems(nx=12, pattern=pattern)
    cap = 10 * 1.1
    for p in probs.pencils:
        r = mceip_mu(p.A0, p.A1, cap)
        assert r.onset.proven and r.all.proven, (p.label, r.onset.status, r.all.status)
        _agrees(r, p.A0, p.A1, cap)
    assert probs.pencils


def test_proof_files_never_replace_an_existing_file(tmp_path):
    """proofs/state_<k>.npz is created exclusively: a file of that name (not this run's) is kept."""
    from app.io.proofs import write_proofs
    A0, A1 = np.eye(2), np.array([[-1.0, 0.2], [0.1, -0.5]])
    r = mceip_mu(A0, A1, 10.0)
    results = minimal_study([{"index": 3, "analyses": {"mceip_mu": {"solutions": []}}}])
    results.states[0].analyses.mceip_mu.proof = {"A0": A0, "A1": A1, "log": r.log.to_json()}    # in memory only
    (tmp_path / "proofs").mkdir()
    (tmp_path / "proofs" / "state_3.npz").write_bytes(b"a user's file")
    with pytest.raises(FileExistsError):
        write_proofs(results, tmp_path)
    assert (tmp_path / "proofs" / "state_3.npz").read_bytes() == b"a user's file"
    fresh = tmp_path / "fresh"
    fresh.mkdir()
    assert [p.name for p in write_proofs(results, fresh)] == ["state_3.npz"]


def test_lp_fast_path_agrees_with_linprog():
    """The prover's LP (app/analyses/mceip_mu/prover/lp.py, SciPy's HiGHS wrapper called directly)
    gives linprog's optimum on random Farkas LPs, feasible and infeasible ones alike."""
    import scipy.optimize

    from app.analyses.mceip_mu.prover import lp
    rng = np.random.default_rng(5)
    for k in range(30):
        s = int(rng.integers(2, 12))
        G = rng.normal(size=(2 * s, s)) + (k % 3) * 0.5
        A_ub = np.hstack([G, np.ones((2 * s, 1))])
        lb = np.array([-1.0] * s + [-np.inf])
        ub = np.array([1.0 if i % 2 else 0.0 for i in range(s)] + [1.0])
        c = np.zeros(s + 1)
        c[-1] = -1.0
        r = lp.solve(c, A_ub, lb, ub)
        ref = scipy.optimize.linprog(c, A_ub=A_ub, b_ub=np.zeros(2 * s), bounds=list(zip(lb, ub)), method="highs")
        assert r.ok and ref.status == 0
        assert r.x[-1] == pytest.approx(ref.x[-1], abs=1e-9)
        assert np.all(A_ub @ r.x <= 1e-9) and np.all(r.x >= lb - 1e-12) and np.all(r.x <= ub + 1e-12)
        assert r.marginals.shape == (2 * s,)


def test_product_argument_witness_is_checked(monkeypatch):
    """A family the sign argument cannot close (dense s = 30 pencil, every support, mu in
    [0, 2.5]) is closed by the product argument (off by default in the prover, switched on
    here: the checker accepts it in any log); the checker re-verifies its witness ``M`` from
    the pencil and rejects it once an entry that must be nonpositive is made positive, or once
    the interval is stretched."""
    from app.analyses.mceip_mu.prover import branch
    monkeypatch.setattr(branch, "USE_RLT", True)
    A0, A1 = _pd_plus_pencil(np.random.default_rng([11, 30]), 30)
    P = branch.Prover(A0, A1, 10.0)
    P.max_nodes = 8
    root, _ = P.tree.add(tuple(range(30)), 0.0, 10.0)
    P.explore(root)
    rlt = [n for n in P.tree.nodes if n.kind == "rlt"]
    assert rlt
    n = rlt[0]
    assert not closing.closes_subsets(P.a0, P.a1, np.arange(30), n.a, n.b, np.ones(30), 0.0)
    ok, _, _, why = checker.check_node(P.a0, P.a1, n, [], 10.0)
    assert ok, why
    M = np.array(n.M)
    i, j = np.unravel_index(np.argmin(M + 1e6 * np.eye(30)), M.shape)     # the most negative off-diagonal
    bad = copy.deepcopy(n)
    bad.M = M.copy()
    bad.M[i, j] = abs(M[i, j]) + 1e-3
    bad.M = bad.M.tolist()
    assert not checker.check_node(P.a0, P.a1, bad, [], 10.0)[0]
    wide = copy.deepcopy(n)
    wide.b = 10.0
    assert not checker.check_node(P.a0, P.a1, wide, [], 10.0)[0]


def test_trusted_kernel_does_not_import_the_prover():
    """The checker's modules (rounding, closing, windows, prooflog, checker) import neither the
    prover nor its LP: a bug there cannot make the checker accept a log."""
    import ast
    import pathlib
    pkg = pathlib.Path(checker.__file__).parent
    for name in ("rounding", "closing", "windows", "prooflog", "checker"):
        tree = ast.parse((pkg / f"{name}.py").read_text(encoding="utf-8"))
        imported = set()
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom):
                imported |= {node.module or ""} | {f"{node.module}.{a.name}" for a in node.names}
            elif isinstance(node, ast.Import):
                imported |= {a.name for a in node.names}
        bad = {m for m in imported if m.split(".")[-1] in ("prover", "branch", "leaves", "heuristics", "lp", "dense_mcp",
                                                           "enumerate")}
        assert not bad, (name, bad)


def test_none_below_cap_without_a_search():
    """The search-free proof of "no critical mu in [0, cap]" (the sign argument on every support,
    intervals halved): when it answers, enumeration finds nothing in [0, cap] and the checker
    accepted its log; on pencils with a solution below the cap it declines (None)."""
    from app.analyses.mceip_mu.proven import mceip_mu_none_below_cap
    rng = np.random.default_rng(17)
    answered = declined = 0
    for _ in range(40):
        s = int(rng.integers(2, 9))
        A0, A1 = _pd_plus_pencil(rng, s, a1_scale=float(rng.uniform(0.05, 3.0)))
        cap = float(rng.uniform(1.0, 30.0))
        vals = [p.value for p in enumerate_patterns(A0, A1, np.arange(s), t_max=cap)]
        r = mceip_mu_none_below_cap(A0, A1, cap)
        if r is None:
            declined += 1
            continue
        answered += 1
        assert not vals, vals
        assert r.certified and r.onset.value is None and r.all.values == []
        assert checker.check_log(A0, A1, r.log).all_ok
        assert all(n.kind in ("cop", "bisect") for n in r.log.nodes)
    assert answered >= 5 and declined >= 5, (answered, declined)


def test_large_family_scaling_by_inverse_iteration():
    """The diagonal scaling of large families (inverse iteration) is the full eigendecomposition's
    ``z / x`` where both exist, on a nonsymmetric matrix with a positive Perron-like pair."""
    from app.analyses.mceip_mu.prover.heuristics import perron_scaling, perron_scaling_large
    rng = np.random.default_rng(3)
    n = 80
    B = rng.uniform(0.0, 1.0, size=(n, n))
    A = n * np.eye(n) - B - 0.3 * B.T @ np.diag(rng.uniform(0, 1, n)) / n   # an M-matrix: x, z > 0
    d_full, d_fast = perron_scaling(A), perron_scaling_large(A)
    assert d_full is not None and d_fast is not None
    assert np.allclose(d_fast, d_full, rtol=1e-6)


def test_a_solution_two_leaves_proved_is_listed_once():
    """The proof can reach one eigenvalue of one support from two leaves of its tree (two verified
    windows that overlap; seen on the mixed-element block at 8 x 4, one rank): the solutions list
    it once, as proven when either leaf proved it, and a candidate the proof did not confirm is
    listed beside it."""
    from types import SimpleNamespace

    from app.analyses.mceip_mu.state import _solutions
    A0, A1 = np.array([[-2.0, 0.0], [0.0, 1.0]]), np.eye(2)     # mu = 2 on the first unknown alone
    support = np.array([True, False])
    x = np.array([1.0, 0.0])

    def leaf(value, lo, hi, proven):
        return SimpleNamespace(value=value, x=x, support=support, enclosure=(lo, hi), min_x=1.0, min_y=1.0,
                               ill_conditioned=False, proven=proven)

    proof = SimpleNamespace(solutions=[leaf(2.0, 1.99, 2.01, False), leaf(2.0 + 1e-15, 1.995, 2.005, True),
                                       leaf(2.0, 1.99, 2.01, False)],
                            all=SimpleNamespace(proven=False), lower_bound=0.0)
    sols = _solutions(A0, A1, 10.0, proof, [], {}, np.arange(2))
    assert len(sols) == 1 and sols[0]["certified"] is True and sols[0]["enclosure"] == [1.995, 2.005]
    other = SimpleNamespace(solutions=[leaf(2.0, 1.99, 2.01, True), leaf(3.0, 2.99, 3.01, False)],
                            all=SimpleNamespace(proven=False), lower_bound=0.0)
    assert [d["value"] for d in _solutions(A0, A1, 10.0, other, [], {}, np.arange(2))] == [2.0, 3.0]
