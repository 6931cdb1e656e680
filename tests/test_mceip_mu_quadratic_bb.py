"""The branch and bound of the quadratic MCEIP-mu (app/analyses/mceip_mu/quadratic/bb.py) and its
checker (app/analyses/mceip_mu/quadratic/check.py) against independent computations: the
floating-point enumeration of every support (enumerate_quadratic), the linear engine when A2 = 0,
and a checker that must reject every edited witness."""
import copy
import time

import numpy as np
import pytest
from test_mceip_mu_quadratic import random_pencil

from app.analyses.mceip_mu.proven import mceip_mu
from app.analyses.mceip_mu.quadratic.bb import prove_bb
from app.analyses.mceip_mu.quadratic.check import check_log
from app.analyses.mceip_mu.quadratic.problem import enumerate_quadratic, quadratic_mu_result
from app.analyses.mceip_mu.quadratic.proof import prove_quadratic

CAP = 30.0


def _support(d):
    return tuple(int(i) for i in np.flatnonzero([p == "slip" for p in d["pattern"]]))


def _assert_same_list(proof, A0, A1, A2, cap=CAP):
    """Proven complete; the proven list is the enumeration's in [0, cap] (same supports, each
    enumerated value inside its enclosure, nothing extra); the onsets agree."""
    assert proof.proven and not proof.report.errors
    found = [d for d in enumerate_quadratic(A0, A1, A2, 14) if d["value"] <= cap]
    assert [p.support for p in proof.solutions] == [_support(d) for d in found]
    for p, d in zip(proof.solutions, found):
        lo, hi = p.enclosure
        assert lo - 1e-10 * hi <= d["value"] <= hi + 1e-10 * hi
        assert hi - lo <= 1e-9 * max(1.0, hi)
    assert (proof.onset is None) == (not found)
    if found:
        assert proof.onset.enclosure[0] - 1e-10 <= found[0]["value"] <= proof.onset.enclosure[1] + 1e-10
    return found


FAST = [(11, 2, -1.0), (12, 1, -1.0), (12, 2, 0.6), (13, 0, -1.0), (14, 0, -1.0)]
SLOW = [(11, 1, -1.0), (11, 1, 0.6), (12, 0, -1.0), (13, 1, -1.0), (13, 0, 0.6), (14, 1, -1.0), (14, 1, 0.6),
        (14, 2, -1.0), (14, 2, 0.6)]


@pytest.mark.parametrize("s, seed, curvature", FAST)
def test_proven_list_equals_the_enumeration(s, seed, curvature):
    A0, A1, A2 = random_pencil(s, 40 * s + seed, curvature)
    t = time.perf_counter()
    proof = prove_bb(A0, A1, A2, CAP)
    print(f"s = {s}: {time.perf_counter() - t:.2f} s, {len(proof.log['nodes'])} nodes, {len(proof.solutions)} solutions")
    _assert_same_list(proof, A0, A1, A2)


@pytest.mark.slow
@pytest.mark.parametrize("s, seed, curvature", SLOW)
def test_proven_list_equals_the_enumeration_more(s, seed, curvature):
    A0, A1, A2 = random_pencil(s, 40 * s + seed, curvature)
    _assert_same_list(prove_bb(A0, A1, A2, CAP), A0, A1, A2)


@pytest.mark.parametrize("seed", [0, pytest.param(1, marks=pytest.mark.slow)])
def test_flat_pencil_agrees_with_the_linear_engine(seed):
    """A2 = 0: the proven list is the linear engine's (app/analyses/mceip_mu) and the enumeration's."""
    A0, A1, _ = random_pencil(11, 900 + seed, 0.0)
    A2 = np.zeros_like(A0)
    proof = prove_bb(A0, A1, A2, 10.0)
    _assert_same_list(proof, A0, A1, A2, cap=10.0)
    lin = mceip_mu(A0, A1, 10.0)
    assert lin.onset.proven and (lin.onset.value is None) == (proof.onset is None)
    on = proof.onset
    if on is not None:
        assert lin.onset.enclosure[0] <= on.enclosure[1] and on.enclosure[0] <= lin.onset.enclosure[1]
    ours = {p.support: p for p in proof.solutions}
    for x in lin.solutions:                  # every solution the linear engine lists is ours
        p = ours[tuple(int(i) for i in np.flatnonzero(x.support))]
        assert p.enclosure[0] - 1e-9 * p.value <= x.value <= p.enclosure[1] + 1e-9 * p.value
    if lin.certified:
        assert len(lin.solutions) == len(proof.solutions)


def test_near_degenerate_pencils():
    """A curvature term at the rounding level (1e-13 of A0) and two slip nodes equal to 1e-9: either
    proven and equal to the enumeration, or not proven (never a wrong proven list)."""
    A0, A1, A2 = random_pencil(11, 77, -1.0)
    tiny = A2 * 1e-13
    _assert_same_list(prove_bb(A0, A1, tiny, CAP), A0, A1, tiny)
    B0, B1, B2 = (M.copy() for M in (A0, A1, A2))
    for M in (B0, B1, B2):
        M[1, :] = M[0, :] * (1 + 1e-9)
        M[:, 1] = M[:, 0] * (1 + 1e-9)
    proof = prove_bb(B0, B1, B2, CAP)
    if not proof.proven:
        assert proof.undecided
        return
    # the exact per-support proof (independent of the branch and bound) finds the same solutions
    exact = prove_quadratic(B0, B1, B2, CAP, max_s=11)
    assert [(p.support, p.enclosure) for p in proof.solutions] == [(p.support, p.enclosure) for p in exact.solutions]
    # the enumeration's extra candidates (a zero reaction within rounding) are flagged ill-conditioned
    proven = {p.support for p in proof.solutions}
    found = [d for d in enumerate_quadratic(B0, B1, B2, 14) if d["value"] <= CAP]
    assert proven <= {_support(d) for d in found}
    assert all(d["ill_conditioned"] for d in found if _support(d) not in proven)


def _proven_log():
    A0, A1, A2 = random_pencil(11, 40 * 11 + 2, -1.0)
    proof = prove_bb(A0, A1, A2, CAP)
    assert proof.proven and proof.solutions
    return (A0, A1, A2), proof


def test_checker_rejects_edited_witnesses():
    P, proof = _proven_log()
    nodes = proof.log["nodes"]
    edits = []
    k = next(i for i, n in enumerate(nodes) if n["kind"] == "farkas")
    edits.append((k, {"w": [0.0] * len(nodes[k]["w"])}))                   # no Farkas vector
    k = next(i for i, n in enumerate(nodes) if n["kind"] == "cop")
    edits.append((k, {"theta": 0.3}))                                       # not an exact split
    k = next(i for i, n in enumerate(nodes) if n["kind"] == "bisect")
    c = nodes[k]["children"][1]
    edits.append((c, {"a": nodes[c]["a"] * (1 + 1e-6)}))                   # a gap in mu
    k = next(i for i, n in enumerate(nodes) if n["kind"] == "branch")
    edits.append((k, {"kind": "cop", "d": [1.0] * len(nodes[k]["U"]), "theta": 0.5}))   # a split called closed
    on = proof.onset
    k = next(i for i, n in enumerate(nodes) if n["kind"] == "leaf" and tuple(n["U"]) == on.support
             and n["a"] <= on.value <= n["b"])
    edits.append((k, {"kind": "nonsing"}))                                  # the onset's leaf called nonsingular
    for k, change in edits:
        log = copy.deepcopy(proof.log)
        log["nodes"][k].update(change)
        rep = check_log(*P, log)
        assert rep.errors and not rep.complete and not rep.onset_proven, (k, change)
    log = copy.deepcopy(proof.log)
    k = next(i for i, n in enumerate(log["nodes"]) if n["kind"] == "cop")
    log["nodes"][k]["U"] = log["nodes"][k]["U"][:-1] + [len(P[0])]          # an index off the pencil
    assert check_log(*P, log).errors
    log = copy.deepcopy(proof.log)
    log["cap"] = 2 * CAP                                                    # a claim beyond the root
    assert check_log(*P, log).errors


def test_onset_is_proven_before_the_list():
    """Nodes above the onset left open (a node budget's log): the checker accepts the onset and
    the list below the first open node, not the complete list."""
    P, proof = _proven_log()
    on = proof.onset
    log = copy.deepcopy(proof.log)
    above = [n for n in log["nodes"] if n["a"] > on.enclosure[1] and n["kind"] != "bisect"]
    assert above
    for n in above:
        n["kind"] = "open"
    rep = check_log(*P, log)
    assert not rep.errors and not rep.complete and rep.onset_proven
    assert rep.onset.support == on.support and rep.onset.enclosure == on.enclosure
    assert rep.open_from == min(n["a"] for n in above)
    log["nodes"][0]["kind"] = "open"                                       # nothing explored
    rep = check_log(*P, log)
    assert not rep.onset_proven and rep.open_from == 0.0


def test_outcome_at_12_and_above_max_slip():
    """quadratic_mu_result: certified at s = 12 (every enumerated solution certified with its
    enclosure, the branch-and-bound log stored); at s = 15 > max_slip nothing is enumerated and the
    solutions come from the proof alone."""
    A0, A1, A2 = random_pencil(12, 40 * 12 + 2, -1.0)
    d = quadratic_mu_result(A0, A1, A2, CAP, 14)
    assert d.certified and d.onset.proven and d.complete.proven
    assert d.proof["log"]["format"] == "mceip-mu-quadratic-bb/1"
    below = [x for x in d.solutions if x.value <= CAP]
    assert below and all(x.certified and x.evidence['enclosure'][0] <= x.value <= x.evidence['enclosure'][1] for x in below)
    assert len(below) == len([x for x in enumerate_quadratic(A0, A1, A2, 14) if x["value"] <= CAP])
    A0, A1, A2 = random_pencil(15, 7, -0.5)
    d = quadratic_mu_result(A0, A1, A2, 10.0, 14)
    assert d.certified and d.complete.proven, d.result
    assert all(x.certified and x.evidence['found_by'] == ["exact proof"] for x in d.solutions)


def test_outcome_with_the_onset_alone(monkeypatch):
    """A branch and bound stopped early (here by its node budget): the outcome
    claims the proven onset, not the list (certified false), and keeps the log for `app check`."""
    import app.analyses.mceip_mu.quadratic.bb as bb
    A0, A1, A2 = random_pencil(12, 40 * 12 + 2, -1.0)
    first = min(d["value"] for d in enumerate_quadratic(A0, A1, A2, 14))
    monkeypatch.setattr(bb, "MAX_NODES", 300)
    d = quadratic_mu_result(A0, A1, A2, CAP, 14)
    assert d.onset.proven and not d.complete.proven and not d.certified, d.result
    assert d.onset.enclosure[0] - 1e-12 <= first <= d.onset.enclosure[1] + 1e-12
    rep = check_log(A0, A1, A2, d.proof["log"])
    assert rep.onset_proven and not rep.complete and rep.open_from < CAP
    monkeypatch.setattr(bb, "MAX_NODES", 2)
    d = quadratic_mu_result(A0, A1, A2, CAP, 14)
    assert not d.onset.proven and not d.certified and "not proven" in d.result


def test_above_max_slip_a_partial_proof_keeps_what_it_proved(monkeypatch):
    """Above ``max_slip`` nothing is enumerated: a branch and bound stopped by its node limit still
    gives its proven onset (the value of the complete proof's onset, inside its enclosure) or, with
    less, its proven lower bound (below the onset), not "not searched"."""
    import app.analyses.mceip_mu.quadratic.bb as bb
    A0, A1, A2 = random_pencil(10, 3, -0.5)
    full = prove_bb(A0, A1, A2, CAP)
    assert full.proven and full.onset is not None
    n = len(full.log["nodes"])
    seen = set()
    for budget in range(2, n, max(1, n // 8)):
        monkeypatch.setattr(bb, "MAX_NODES", budget)
        d = quadratic_mu_result(A0, A1, A2, CAP, 8)             # s = 10 > max_slip = 8
        assert not d.certified and not d.complete.proven
        if prove_bb(A0, A1, A2, CAP).report.open_from == 0.0:   # nothing proven at this budget
            seen.add("nothing")
            assert d.result.startswith("not searched") and d.complete.interval == [0.0, 0.0]
        elif d.onset.proven:
            seen.add("onset")
            assert d.onset.enclosure[0] <= full.onset.value <= d.onset.enclosure[1]
            assert d.solutions and all(x.certified for x in d.solutions)
        else:
            seen.add("bound")
            lb = d.complete.interval[1]
            assert 0 < lb <= full.onset.enclosure[0] and f"[0, {lb:.6g}]" in d.result
    assert {"onset", "bound"} <= seen


@pytest.mark.slow
def test_agrees_with_the_per_support_proof_at_9_and_10():
    """Soundness harness: on 12 random pencils (s = 9, 10, curvature of both signs and none, caps
    10 and 30) the branch and bound's proven list is the exact per-support proof's (same supports,
    overlapping enclosures), both complete."""
    rng = np.random.default_rng(21)
    n_sol = 0
    for k in range(12):
        s = int(rng.integers(9, 11))
        curvature = float(rng.choice([-1.5, -0.5, 0.0, 0.4, 1.2]))
        A0, A1, A2 = random_pencil(s, 7000 + k, curvature)
        cap = float(rng.choice([10.0, 30.0]))
        b, e = prove_bb(A0, A1, A2, cap), prove_quadratic(A0, A1, A2, cap, max_s=10)
        assert b.proven and e.proven
        assert [p.support for p in b.solutions] == [p.support for p in e.solutions]
        assert all(x.enclosure[0] <= y.enclosure[1] and y.enclosure[0] <= x.enclosure[1]
                   for x, y in zip(b.solutions, e.solutions))
        n_sol += len(e.solutions)
    assert n_sol > 5
