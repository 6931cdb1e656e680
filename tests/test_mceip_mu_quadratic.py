"""The quadratic MCEIP-mu enumeration (app/analyses/mceip_mu/quadratic/problem.py) against independent
computations: the flat enumeration (24)-(26) when A2 = 0, and a per-support QZ reference written
here (scipy.linalg.eig on the first companion linearisation, numpy sign checks)."""
import itertools
import time

import numpy as np
import pytest
import scipy.linalg

from app.analyses.enumerate import enumerate_mceip
from app.analyses.mceip_mu.quadratic.problem import enumerate_quadratic, quadratic_mu_result
from app.analyses.mceip_mu.quadratic.proof import prove_quadratic


def random_pencil(s, seed, curvature):
    rng = np.random.default_rng(seed)
    B = rng.normal(size=(s, s))
    A0 = B @ B.T + s * np.eye(s)                      # S Ŝ_TT S: SPD
    A1 = rng.normal(size=(s, s)) * 1.5
    G = np.diag(curvature * rng.uniform(0.2, 1.0, size=s))
    return A0 + G, A1, G


def reference(A0, A1, A2):
    """Per support J: every finite real mu >= 0 of the QZ of [[0, I], [-A0, -A1]] - mu [[I, 0], [0, A2]],
    its null vector by SVD, x_J > 0 and y on the rest >= 0 (relative 1e-9)."""
    s = A0.shape[0]
    sc = np.max(np.abs(np.diag(A0)))
    out = []
    for k in range(1, s + 1):
        for J in itertools.combinations(range(s), k):
            J = list(J)
            a0, a1, a2 = (A[np.ix_(J, J)] for A in (A0, A1, A2))
            Z, I = np.zeros((k, k)), np.eye(k)
            w = scipy.linalg.eig(np.block([[Z, I], [-a0, -a1]]), np.block([[I, Z], [Z, a2]]), right=False)
            for mu in w[np.isfinite(w)]:
                if abs(mu.imag) > 1e-6 * max(1, abs(mu.real)) or mu.real < 0:
                    continue
                mu = mu.real
                _, sv, Vh = np.linalg.svd(a0 + mu * a1 + mu * mu * a2)
                v = Vh[-1] * np.sign(Vh[-1].sum())
                if np.min(v) <= 0:
                    continue
                x = np.zeros(s)
                x[J] = v / v.sum()
                y = (A0 + mu * A1 + mu * mu * A2) @ x / sc
                if np.delete(y, J).size and np.min(np.delete(y, J)) < -1e-9:
                    continue
                if not any(abs(m - mu) < 1e-9 * max(1, mu) and p == tuple(J) for m, p in out):
                    out.append((mu, tuple(J)))
    return sorted(out)


@pytest.mark.parametrize("seed", range(6))
def test_flat_pencil_equals_the_linear_enumeration(seed):
    A0, A1, _ = random_pencil(6, seed, 0.0)
    lin = enumerate_mceip(A0, A1, np.arange(6), 14)
    quad = enumerate_quadratic(A0, A1, np.zeros((6, 6)), 14)
    assert [d["pattern"] for d in quad] == [d["pattern"] for d in lin]
    assert [d["value"] for d in quad] == pytest.approx([d["value"] for d in lin], rel=1e-10)
    for q, l in zip(quad, lin):
        assert q["x_Ts"] == pytest.approx(l["x_Ts"], abs=1e-9)


@pytest.mark.parametrize("curvature", [-1.5, -0.3, 0.4, 2.0])
@pytest.mark.parametrize("seed", range(4))
def test_quadratic_pencil_equals_the_qz_reference(seed, curvature):
    A0, A1, A2 = random_pencil(6, 100 + seed, curvature)
    got = enumerate_quadratic(A0, A1, A2, 14)
    ref = reference(A0, A1, A2)
    assert [tuple(np.flatnonzero([p == "slip" for p in d["pattern"]])) for d in got] == [j for _, j in ref]
    assert [d["value"] for d in got] == pytest.approx([m for m, _ in ref], rel=1e-9)
    for d in got:                                      # each one solves the quadratic MCEIP
        x, mu = np.array(d["x_Ts"]), d["value"]
        y = (A0 + mu * A1 + mu * mu * A2) @ x
        sup = x > 0
        assert np.abs(y[sup]).max() < 1e-9 * np.abs(A0).max() and (y[~sup] >= -1e-9 * np.abs(A0).max()).all()


@pytest.mark.parametrize("curvature", [-1.0, 0.5])
@pytest.mark.parametrize("seed", range(3))
def test_exact_proof_against_the_qz_reference(seed, curvature):
    """The exact proof's list on [0, 50] is the reference's (each value inside its enclosure)."""
    A0, A1, A2 = random_pencil(6, 200 + seed, curvature)
    proof = prove_quadratic(A0, A1, A2, 50.0)
    ref = [(m, j) for m, j in reference(A0, A1, A2) if m <= 50.0]
    assert proof.proven and not proof.undecided
    assert [p.support for p in proof.solutions] == [j for _, j in ref]
    for p, (m, _) in zip(proof.solutions, ref):
        lo, hi = p.enclosure
        assert lo - 1e-12 * m <= m <= hi + 1e-12 * m


def test_exact_proof_refuses_what_it_cannot_decide():
    """A support whose determinant vanishes identically (two equal rows and columns) cannot be
    decided: the result is found, not proven."""
    A0, A1, A2 = random_pencil(3, 9, -0.5)
    for A in (A0, A1, A2):
        A[2, :] = A[1, :]
        A[:, 2] = A[:, 1]
    proof = prove_quadratic(A0, A1, A2, 50.0)
    assert not proof.proven and any("vanishes identically" in why for _, why in proof.undecided)
    d = quadratic_mu_result(A0, A1, A2, 50.0, 14)
    assert d.certified is False and "not proven" in d.result


def test_above_max_slip_and_at_14():
    """s = 15 > max_slip: not enumerated, and without a proof (certify off) not searched; s = 14:
    enumerated, and proven by the branch and bound (s > PROOF_MAX_S)."""
    A0, A1, A2 = random_pencil(15, 7, -0.5)
    d = quadratic_mu_result(A0, A1, A2, 10.0, 14, certify=False)
    assert d.solutions == [] and d.result.startswith("not searched") and d.certified is False
    A0, A1, A2 = random_pencil(14, 8, -0.5)
    t = time.perf_counter()
    d = quadratic_mu_result(A0, A1, A2, 10.0, 14)
    print(f"s = 14: {time.perf_counter() - t:.2f} s, {len(d.solutions)} solution(s)")
    assert time.perf_counter() - t < 30
    assert d.certified and d.onset.proven and d.complete.proven, d.result
    assert d.certificate.detail["nodes"] > 1                       # the branch and bound, not the per-support proof


def test_exact_proof_agrees_with_the_enumeration_on_40_pencils():
    """Soundness harness: on 40 random pencils (s = 2 .. 7, curvature of both signs) every proven
    list on [0, 30] equals the floating-point enumeration's (supports, values in the enclosures),
    and every proof is complete."""
    rng = np.random.default_rng(2026)
    n_sol = 0
    for k in range(40):
        s = int(rng.integers(2, 8))
        A0, A1, A2 = random_pencil(s, 1000 + k, float(rng.choice([-1.2, -0.4, 0.3, 1.5])))
        proof = prove_quadratic(A0, A1, A2, 30.0)
        assert proof.proven, proof.undecided[:2]
        found = [d for d in enumerate_quadratic(A0, A1, A2, 14) if d["value"] <= 30.0]
        assert [tuple(np.flatnonzero([p == "slip" for p in d["pattern"]])) for d in found] == \
            [p.support for p in proof.solutions]
        for d, p in zip(found, proof.solutions):
            lo, hi = p.enclosure
            assert lo - 1e-10 * hi <= d["value"] <= hi + 1e-10 * hi
        n_sol += len(found)
    assert n_sol > 20                                    # the harness exercises solutions, not only absences


def test_a_continuum_of_solutions_is_not_proven():
    """Two identical decoupled slip nodes: at the root of a(mu) every x >= 0 on both is a solution
    (a double root of det on the support {0, 1}): the proof leaves it undecided."""
    A0, A1, A2 = np.diag([2.0, 2.0]), np.diag([-3.0, -3.0]), np.diag([0.5, 0.5])
    proof = prove_quadratic(A0, A1, A2, 50.0)
    assert not proof.proven and any("multiple root" in why for _, why in proof.undecided)
