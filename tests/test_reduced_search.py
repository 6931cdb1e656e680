"""MCEIP-lambda^2 searched on the exact slip-node reduction where its proof fails
(app/analyses/mceip_lambda2/reduced_search.py), as it is above ``mcp.lambda2_full_search_max_dofs``:
the solutions it finds are those of the SNES VI search on the full system (an independent
computation: another formulation, another solver), state by state, along paths held at a friction
coefficient above the MCEIP-mu onset (a divergence rate exists)."""
import copy

import numpy as np
import pytest
from conftest import run_scene
from test_two_particles import CASES as TABLE1

BLOCK = {"name": "rs", "system": {"type": "block", "length": 80.0, "height": 40.0, "thickness": 9.6, "nx": 20,
                                  "ny": 10, "pattern": "crossed", "E": 5.0, "nu": 0.48, "density": 1.2e-9},
         "mu": 1.1, "loading": {"normal_force": 55.0, "normal_steps": 10, "tangential_step": 0.02,
                                "tangential_max": 10.0},
         "analyses": ["mceip_mu", "mceip_lambda2"]}


def _lambda2(res: dict) -> list[dict]:
    return [s["analyses"]["mceip_lambda2"] for s in res["states"]
            if isinstance((s.get("analyses") or {}).get("mceip_lambda2"), dict)]


@pytest.mark.parametrize("nx, mu", [(20, 2.0), (10, 2.5), (10, 3.0)])
def test_the_search_on_the_reduction_finds_the_full_systems_solutions(nx, mu):
    data = copy.deepcopy(BLOCK)
    data["system"].update(nx=nx, ny=nx // 2)
    data["mceip_lambda2_mu"] = mu
    full = _lambda2(run_scene(data))
    data["settings"] = {"mcp": {"lambda2_full_search_max_dofs": 0}}
    reduced = _lambda2(run_scene(data))
    assert len(full) == len(reduced)
    searched = 0
    for f, r in zip(full, reduced):
        if f["certified"]:                      # proven on the reduction: the same answer
            assert r["result"] == f["result"] and r["certified"]
            continue
        searched += 1
        assert not r["certified"]
        assert "searched_on_reduction" in r["search"], r["search"].get("note")
        ff = [s for s in f["solutions"] if not s["ill_conditioned"]]
        rr = r["solutions"]
        assert len(rr) == len(ff), (f["result"], r["result"])
        for a, b in zip(sorted(ff, key=lambda s: s["value"]), rr):
            assert abs(a["value"] - b["value"]) <= 1e-9 * a["value"]
            assert a["pattern"] == b["pattern"]
            assert np.allclose(a["x_Ts"], b["x_Ts"], atol=1e-8)
        # none outside the intervals it searched, which the proof set aside
        gaps = r["certificate"]["detail"]["proven_empty_except"]
        assert all(any(lo <= s["value"] <= hi for lo, hi in gaps) for s in rr)
    assert searched > 0


@pytest.mark.parametrize("slip_from, mu", [(0, 2.0), (0, 3.0)])
def test_the_reductions_eigenpairs_are_the_full_pencils(slip_from, mu):
    """(17)-(18) on the reduction (reduced_search.eigenpairs, used for the sufficient condition where
    MCEIP-lambda^2 was searched on the reduction): in the intervals the proof set aside, the real
    eigenvalues lambda^2 > 0 of the full reduced pencil (K*(mu), M*(mu)) whose eigenvector has
    x_Ts >= 0, from LAPACK on the dense pencils (an independent computation), are found, to 1e-9,
    and outside them there is none (10 x 5 block, every node slipping, where the proof fails)."""
    import scipy.linalg
    from mpi4py import MPI
    from test_dynamic_contact import BLOCK as SMALL
    from test_dynamic_contact import _classification, _contact

    from app.analyses.mceip_lambda2 import dynamic_contact, exact
    from app.analyses.mceip_lambda2 import reduced_search as rs
    from app.analyses.pencils.reduced import dense as to_dense
    from app.analyses.pencils.state import StatePencils
    from app.common.stages import Stages
    from app.scene.schema import parse_scene
    from app.systems.block.path import build

    with build(parse_scene(SMALL).system, MPI.COMM_WORLD, Stages()) as system:
        dc = dynamic_contact.DynamicContact.from_dense(to_dense(system.K), to_dense(system.mass()), *_contact(system))
        cls = _classification(system, slip_from)
        start = exact.start_bound(dc, cls, mu)
        proven, T, detail = exact.prove_no_solution(dc, cls, mu, start, max_failed=16)
        assert detail.get("covered")
        gaps = detail.get("failed", [])
        got = rs.eigenpairs(dc, cls, mu, gaps)
        p = StatePencils(system, cls)
        try:
            Ks, Ms = p.star(mu)
            Kd, Md = to_dense(Ks), to_dense(Ms)
            comp = p.space.comp
        finally:
            p.destroy()
    w, V = scipy.linalg.eig(-Kd, Md)
    want = []
    for lam, v in zip(w, V.T):
        if abs(lam.imag) > 1e-9 * abs(lam) or lam.real <= 0:
            continue
        x = v.real[comp]
        x = x if x.sum() >= 0 else -x
        if x.min() >= -1e-8 * np.abs(x).max():
            want.append(lam.real)
    want = sorted(want)
    assert want and gaps                       # an admissible eigenpair exists, the proof set intervals aside
    assert all(any(lo <= t <= hi for lo, hi in gaps) for t in want)        # none outside the intervals
    found = [t for t, x, _ in got if (x if x.sum() >= 0 else -x).min() >= -1e-8 * np.abs(x).max()]
    assert len(found) == len(want), (found, want)
    assert np.allclose(found, want, rtol=1e-9, atol=0)
    assert all(any(abs(t - u) <= 1e-9 * u for t, _, _ in got) for u in want)


@pytest.mark.parametrize("signs, mu, count", TABLE1)
def test_the_paper_two_particles_on_the_reduction(signs, mu, count):
    """The paper's two particles (Table 1) with the search on the reduction forced: MCEIP-lambda^2's
    solutions are the closed form's, and (17)-(18) from the reduction equals the eigensolver on the
    full pencils."""
    from test_two_particles import PHI, K, M, analytic_lambda2, scene

    expected = sorted(v for v, _, _ in analytic_lambda2(K, M, PHI, mu, *signs))
    assert len(expected) == count
    runs = []
    for max_dofs in (10**8, 0):
        sc = scene(signs, mu, ["sufficient", "mceip_lambda2"])
        sc["settings"] = {"mcp": {"lambda2_full_search_max_dofs": max_dofs}}
        runs.append(run_scene(sc)["states"][0]["analyses"])
    full, reduced = runs
    got = sorted(s["value"] for s in reduced["mceip_lambda2"]["solutions"])
    assert got == pytest.approx(expected, rel=1e-9)
    assert reduced["sufficient"]["satisfied"] == full["sufficient"]["satisfied"]
    assert reduced["sufficient"]["lambda2"] == pytest.approx(full["sufficient"]["lambda2"], rel=1e-9)
    if count:
        assert "searched_on_reduction" in reduced["mceip_lambda2"]["search"]
        assert "exact slip-node reduction" in reduced["sufficient"]["eigensolver"]
