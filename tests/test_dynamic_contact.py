"""MCEIP-lambda^2 on the contact DOFs at any size (app/analyses/mceip_lambda2/exact.py): the dynamic
contact Schur complement Z(t) from sparse factorisations of K + t M equals the one from the dense
(K, M) eigen-decomposition, the proofs on both agree, and the sufficient condition (17)-(18) decided
by MCEIP-lambda^2 equals SLEPc's answer on the full pencil."""
import copy

import numpy as np
import pytest
from conftest import run_scene
from mpi4py import MPI
from test_two_particles import CASES, PHI, K, M, analytic_lambda2, scene

from app.analyses.mceip_lambda2 import dynamic_contact, exact
from app.analyses.pencils.reduced import dense as to_dense
from app.common.stages import Stages
from app.loading.classify import SLIP, STICK, Classification
from app.scene.schema import parse_scene
from app.systems.block.path import build

BLOCK = {"name": "b", "system": {"type": "block", "length": 80.0, "height": 40.0, "thickness": 9.6, "nx": 10,
                                 "ny": 5, "pattern": "crossed", "E": 5.0, "nu": 0.48, "density": 1.2e-9},
         "mu": 1.1, "loading": {"normal_force": 55.0, "normal_steps": 4, "tangential_step": 0.05,
                                "tangential_max": 10.0}}


@pytest.fixture(scope="module")
def block():
    sc = parse_scene(BLOCK)
    with build(sc.system, MPI.COMM_WORLD, Stages()) as system:
        K, Mm = system.K, system.mass()
        dense = dynamic_contact.DynamicContact.from_dense(to_dense(K), to_dense(Mm), *_contact(system))
        sparse = dynamic_contact.DynamicContact.from_sparse(K, Mm, *_contact(system))
        yield system, dense, sparse


def _contact(system):
    dofs = np.array([[nd.dof_T, nd.dof_N] for nd in system.nodes]).ravel()
    signs = np.array([[nd.sign_T, nd.sign_N] for nd in system.nodes], dtype=float).ravel()
    return dofs, signs


@pytest.mark.parametrize("t", [0.0, 1.0e3, 1.0e6, 3.0e7, 1.0e9, 1.0e11])
def test_sparse_dynamic_schur_complement_equals_the_modal_one(block, t):
    """Z(t) = (B (K + t M)^-1 B^T)^-1 both ways, from t = 0 (the static contact Schur complement,
    which also equals the system's own) to t far above the mesh's largest omega^2."""
    system, dense, sparse = block
    Zd, Hd = dense.at(t)
    Zs, Hs = sparse.at(t)
    assert np.linalg.norm(Zs - Zd) <= 1e-10 * np.linalg.norm(Zd)
    assert np.array_equal(Hs, Hd)
    if t == 0.0:
        Sc = system.contact_schur()
        assert np.linalg.norm(Zs - Sc) <= 1e-10 * np.linalg.norm(Sc)


def test_z_increases_with_t_and_is_cached(block):
    """dZ/dt is a generalised mass (positive definite, docs/method.md section 7); evaluations are
    cached per t, so a second proof on the same grid factorises nothing new."""
    _, _, sparse = block
    Z1, _ = sparse.at(1.0e6)
    Z2, _ = sparse.at(2.0e6)
    assert np.linalg.eigvalsh(Z2 - Z1).min() > 0
    n = sparse.evaluations
    sparse.at(1.0e6)
    assert sparse.evaluations == n


def _classification(system, slip_from: int) -> Classification:
    """The nodes from ``slip_from`` on in impending slip (sign +1), the others stuck: the block's
    states under leftward shear (slip spreads from B towards A)."""
    n = len(system.nodes)
    status = [STICK] * slip_from + [SLIP] * (n - slip_from)
    return Classification(status=tuple(status), signs=tuple(1 if st == SLIP else 0 for st in status))


@pytest.mark.parametrize("slip_from", [8, 4, 0])
def test_the_proof_is_the_same_on_both_reductions(block, slip_from):
    """prove_no_solution reaches the same verdict and bound T on both reductions (the same grid
    of t), for few and for all nodes slipping."""
    system, dense, sparse = block
    cls = _classification(system, slip_from)
    got = [exact.prove_no_solution(dc, cls, 1.1, 1.0e9) for dc in (dense, sparse)]
    assert got[0][0] == got[1][0] and got[0][1] == got[1][1], got


@pytest.mark.parametrize("signs,mu,count", CASES)
def test_two_particles_sparse_reduction(signs, mu, count):
    """The paper's two particles with the sparse reduction forced (lambda2_exact_max_dofs: 0): the
    same MCEIP-lambda^2 answer as the dense one, and never "proven" where a closed-form solution
    exists."""
    expected = analytic_lambda2(K, M, PHI, mu, *signs)
    runs = []
    for max_dofs in (1500, 0):
        sc = scene(signs, mu, ["necessary", "mceip_lambda2"])
        sc.setdefault("settings", {}).setdefault("mcp", {})["lambda2_exact_max_dofs"] = max_dofs
        runs.append(run_scene(sc)["states"][0]["analyses"]["mceip_lambda2"])
    dense_run, sparse_run = runs
    assert sparse_run["certified"] == dense_run["certified"] and sparse_run["result"] == dense_run["result"]
    assert [s["value"] for s in sparse_run["solutions"]] == pytest.approx([s["value"] for s in dense_run["solutions"]],
                                                                          rel=1e-10)
    if expected:
        assert sparse_run["certified"] is False


def _distinct_states(*variants):
    """The block's study run once per ``(lambda2_exact_max_dofs, analyses)`` of ``variants``: per
    distinct classification with analyses, the tuple of its state in each run."""
    runs = []
    for max_dofs, analyses in variants:
        sc = copy.deepcopy(BLOCK)
        sc["analyses"] = analyses
        sc["settings"] = {"mcp": {"lambda2_exact_max_dofs": max_dofs}}
        runs.append(run_scene(sc)["states"])
    return [group for group in zip(*runs)
            if group[0].get("analyses_shared_with") is None and group[0].get("analyses")]


def test_study_answers_do_not_depend_on_the_reduction():
    """The block's study: MCEIP-lambda^2 on the sparse reduction (lambda2_exact_max_dofs: 0) gives
    the dense reduction's answers at every classification, and the sufficient condition decided by
    MCEIP-lambda^2 is SLEPc's answer on the full pencil (a study without MCEIP-lambda^2)."""
    decided = 0
    for d, s, e in _distinct_states((20_000, ["necessary", "sufficient", "mceip_lambda2"]),
                                    (0, ["necessary", "sufficient", "mceip_lambda2"]),
                                    (20_000, ["necessary", "sufficient"])):
        a, b, c = d["analyses"], s["analyses"], e["analyses"]
        for key in ("result", "certified"):
            assert a["mceip_lambda2"][key] == b["mceip_lambda2"][key], (d["index"], key)
        assert a["sufficient"]["satisfied"] == b["sufficient"]["satisfied"] == c["sufficient"]["satisfied"]
        assert a["sufficient"]["lambda2"] == b["sufficient"]["lambda2"] == c["sufficient"]["lambda2"]
        if a["sufficient"]["eigensolver"].startswith("none: "):
            decided += 1
            assert "eigensolver" in c["sufficient"] and not c["sufficient"]["eigensolver"].startswith("none")
    assert decided >= 3        # the path has several classifications with slip nodes


def test_sparse_reduction_on_two_ranks(tmp_path):
    """K and M gathered on rank 0, which factorises K + t M and proves alone: the same
    MCEIP-lambda^2 and sufficient-condition answers as one rank."""
    import yaml
    from conftest import results_on_ranks
    sc = copy.deepcopy(BLOCK)
    sc["analyses"] = ["necessary", "sufficient", "mceip_lambda2"]
    sc["settings"] = {"mcp": {"lambda2_exact_max_dofs": 0}}
    path = tmp_path / "scene.yaml"
    path.write_text(yaml.safe_dump(sc))
    runs = results_on_ranks(path, tmp_path)
    shown = 0
    for one, two in zip(runs[1]["states"], runs[2]["states"]):
        if one.get("analyses_shared_with") is not None or not one.get("analyses"):
            continue
        a, b = one["analyses"], two["analyses"]
        for key in ("result", "certified", "solutions"):
            assert a["mceip_lambda2"][key] == b["mceip_lambda2"][key], (one["index"], key)
        assert a["sufficient"]["satisfied"] == b["sufficient"]["satisfied"]
        shown += a["mceip_lambda2"]["result"] == "proven: no solution with lambda^2 >= 0"
    assert shown >= 3


def test_contact_signs_are_the_necessary_condition(block):
    """The signs of (19) from the Schur complements onto the kept contact DOFs equal those of the
    full-size eigenvalues (SLEPc, app/analyses/conditions/full_size.py) for stick, slip and free nodes."""
    from app.analyses.conditions.full_size import necessary
    from app.analyses.pencils.state import StatePencils
    from app.loading.classify import FREE
    system, dense, sparse = block
    sc = parse_scene(BLOCK)
    n = len(system.nodes)
    cases = [_classification(system, k) for k in (n, 8, 4, 0)]
    cases.append(Classification(status=tuple([FREE] * 2 + [SLIP] * (n - 4) + [FREE] * 2),
                                signs=tuple([0] * 2 + [1] * (n - 4) + [0] * 2)))
    seen = set()
    for cls in cases:
        for mu in (0.3, 1.1, 3.0):
            p = StatePencils(system, cls)
            try:
                nec = necessary(*p.K(), *p.M(), mu, sc.settings.eig)
            finally:
                p.destroy()
            for dc in (dense, sparse):
                signs = exact.contact_signs(dc, cls, mu)
                assert signs.k_pd == (nec.min_eig_K_sym_relative > 1e-8), (cls.counts(), mu)
                assert signs.m_pd == (nec.min_eig_M_sym_relative > 1e-8)
                assert signs.m_psd
            seen.add(signs.k_pd)
    assert seen == {True, False}


def test_lambda2_without_the_necessary_condition():
    """Without (19) in the scene MCEIP-lambda^2 decides its signs and start bound on the contact
    DOFs: the same answers as with (19)'s full-size eigenvalues, on both reductions."""
    decided = 0
    for w, d, s in _distinct_states((1500, ["necessary", "sufficient", "mceip_lambda2"]),
                                    (1500, ["sufficient", "mceip_lambda2"]),
                                    (0, ["sufficient", "mceip_lambda2"])):
        for other in (d, s):
            for key in ("result", "certified", "solutions"):
                assert other["analyses"]["mceip_lambda2"][key] == w["analyses"]["mceip_lambda2"][key], (w["index"], key)
            assert other["analyses"]["sufficient"]["satisfied"] == w["analyses"]["sufficient"]["satisfied"]
        decided += "contact_signs" in s["analyses"]["mceip_lambda2"]["search"]
    assert decided >= 3


def test_never_shown_absent_above_the_onset():
    """Soundness on the paper's kind of state: above the final state's proven MCEIP-mu onset
    (all nodes slipping) MCEIP-lambda^2 has a divergence mode (the paper: "choosing mu > 1.71 the
    MCEIP-lambda^2 has ... a positive eigenvalue"); the sparse reduction must not show it absent,
    and the search finds it, with or without (19) in the scene."""
    sc = copy.deepcopy(BLOCK)
    sc["analyses"] = ["mceip_mu"]
    onset = run_scene(sc)["states"][-1]["analyses"]["mceip_mu"]["onset"]["value"]
    for analyses in (["mceip_lambda2"], ["necessary", "mceip_lambda2"]):
        sc = copy.deepcopy(BLOCK)
        sc.update(analyses=analyses, mceip_lambda2_mu=onset + 0.3,
                  settings={"mcp": {"lambda2_exact_max_dofs": 0}})
        final = run_scene(sc)["states"][-1]["analyses"]["mceip_lambda2"]
        assert final["certified"] is False and final["solutions"], final["result"]
        assert all(x["value"] > 0 for x in final["solutions"])


def test_warm_eigenvectors_change_no_value():
    """(19) along a sequence of classifications with the previous classification's eigenvalues
    and eigenvectors as shifts and start vectors (the path's way) gives the values of cold solves;
    the start vectors move between the classifications' kept DOFs through the system's numbering."""
    from app.analyses.conditions.full_size import necessary
    from app.analyses.pencils.reduced import reduced_space
    from app.analyses.pencils.state import StatePencils
    sc = parse_scene(dict(BLOCK, system=dict(BLOCK["system"], nx=20, ny=10)))   # above eig.dense_limit
    with build(sc.system, MPI.COMM_WORLD, Stages()) as system:
        rows = system.K.getOwnershipRange()
        n = len(system.nodes)
        hints: dict = {}
        for slip_from in (n - 2, n - 4, n - 6, n - 10):
            cls = _classification(system, slip_from)
            space = reduced_space(system, cls)
            y = np.arange(1.0, space.kept.getLocalSize() + 1)
            assert np.array_equal(space.from_system(space.to_system(y, rows), rows), y)
            p = StatePencils(system, cls)
            try:
                warm = necessary(*p.K(), *p.M(), 1.1, sc.settings.eig, hints, space=(space, rows))
                cold = necessary(*p.K(), *p.M(), 1.1, sc.settings.eig)
            finally:
                p.destroy()
                space.destroy()
            for name in ("K", "M"):
                a, b = getattr(warm, f"min_eig_{name}_sym"), getattr(cold, f"min_eig_{name}_sym")
                assert a == pytest.approx(b, rel=1e-9), (slip_from, name)
        assert hints["K_vector"].shape == (rows[1] - rows[0],)


@pytest.mark.parametrize("name", ["half_disk_cylinder.yaml", "half_disk_seat.yaml"])
def test_the_reduction_on_a_curved_obstacle_is_the_full_pencils_schur_complement(name):
    """On a curved obstacle the reduced pencils hold the slip nodes' contact frames and K* the
    curvature term (1 + mu^2) G (docs/method.md section 8). The exact slip-node reduction of
    MCEIP-lambda^2 (app/analyses/mceip_lambda2/exact.py) against the dense Schur complement of
    the app's full reduced pencil K*(mu) + t M*(mu) onto the slip nodes' x_Ts, along the path of
    the half-disk on a cylinder and in a seat, at three t (1e-8 of the scale); and the signs of
    (19) from the contact DOFs against the full pencils' smallest eigenvalues."""
    import re

    import yaml
    from conftest import ROOT

    from app.analyses.mceip_lambda2 import dynamic_contact as l2d
    from app.analyses.mceip_lambda2 import exact as l2x
    from app.analyses.pencils import curvature
    from app.loading.classify import ZERO, classify
    from app.scene.schema import parse_scene
    from app.study.run import study
    src = ROOT / "app" / "scenes" / "gmsh"
    data = yaml.safe_load(re.sub(r"^outputs:.*$", "", (src / name).read_text(), flags=re.M))
    data["system"]["file"] = str(src / data["system"]["file"])
    data["analyses"] = []
    scene = parse_scene(data)
    mu = scene.mu

    def inspect(system, states, cache):
        dc = l2d.dynamic_contact(system, scene.settings.mcp.lambda2_exact_max_dofs)
        seen, checked = set(), 0
        for st in states:
            cls = curvature.attach(classify(st, mu, scene.settings.classify_rtol), st, system)
            if cls.key in seen or ZERO in cls.status or not len(cls.slip):
                continue
            seen.add(cls.key)
            assert curvature.is_curved(cls) and cls.rotated()
            Ks, Ms, comp, f = _full_pencils(system, cls, mu)
            red = l2x.Reduction(dc, cls, mu)
            for t in (0.0, 1e4, 1e8):
                A = Ks + t * Ms
                S = A[np.ix_(comp, comp)] - A[np.ix_(comp, f)] @ np.linalg.solve(A[np.ix_(f, f)], A[np.ix_(f, comp)])
                Sh, Qt = red.at(t)
                scale = np.abs(np.diag(S)).max()
                assert np.abs(0.5 * (S + S.T) - (Sh + Qt)).max() <= 1e-8 * scale, (cls.counts(), t)
            signs = l2x.contact_signs(dc, cls, mu)
            assert signs.k_pd == (np.linalg.eigvalsh(0.5 * (Ks + Ks.T))[0] > 0), cls.counts()
            checked += 1
        return {"checked": checked}

    res = study(scene, MPI.COMM_WORLD, None, inspect=inspect)
    assert res.inspection["checked"] >= 5


@pytest.mark.parametrize("fallback", [False, True])
def test_the_split_is_the_definitions(block, fallback, monkeypatch):
    """``Reduction.at``'s ``Sh(t)`` is the Schur complement of ``sym(K*(mu) + t M*(mu))`` onto the
    slip nodes' ``x_Ts`` and ``Q(t) = sym S(t) - Sh(t)`` is positive semidefinite (docs/method.md
    section 7), against the app's full reduced pencils (dense), with free, stuck and slipping
    nodes; also through the LU factorisations used where the free block's Cholesky fails."""
    import scipy.linalg

    from app.loading.classify import FREE
    system, dense, sparse = block
    if fallback:
        def refuse(*args, **kwargs):
            raise np.linalg.LinAlgError("refused by the test")
        monkeypatch.setattr(scipy.linalg, "cholesky", refuse)
    n = len(system.nodes)
    status = [FREE] * 2 + [STICK] * 2 + [SLIP] * (n - 6) + [FREE] * 2
    signs = tuple(-1 if (i % 3 == 0) else 1 for i in range(n))
    cls = Classification(status=tuple(status), signs=tuple(sg if st == SLIP else 0 for st, sg in zip(status, signs)))
    mu = 1.1
    Ks, Ms, comp, f = _full_pencils(system, cls, mu)
    for dc in (dense, sparse):
        red = exact.Reduction(dc, cls, mu)
        for t in (0.0, 1e4, 1e8):
            A = Ks + t * Ms
            G = 0.5 * (A + A.T)
            S = A[np.ix_(comp, comp)] - A[np.ix_(comp, f)] @ np.linalg.solve(A[np.ix_(f, f)], A[np.ix_(f, comp)])
            Sh = G[np.ix_(comp, comp)] - G[np.ix_(comp, f)] @ np.linalg.solve(G[np.ix_(f, f)], G[np.ix_(f, comp)])
            got_Sh, got_Q = red.at(t)
            scale = np.abs(np.diag(S)).max()
            assert np.abs(got_Sh - Sh).max() <= 1e-8 * scale, t
            assert np.abs(got_Q - (0.5 * (S + S.T) - Sh)).max() <= 1e-8 * scale, t
            assert np.linalg.eigvalsh(got_Q).min() >= -1e-8 * scale, t


def _full_pencils(system, cls, mu):
    """The app's full reduced pencils ``K*(mu)``, ``M*(mu)`` of ``cls`` (dense), the positions of the
    slip nodes' ``x_Ts`` in them and of the other DOFs."""
    from app.analyses.pencils.state import StatePencils
    p = StatePencils(system, cls)
    try:
        Ks, Ms = (to_dense(A) for A in p.star(mu))
        comp = p.space.comp
    finally:
        p.destroy()
    return Ks, Ms, comp, np.setdiff1d(np.arange(Ks.shape[0]), comp)
