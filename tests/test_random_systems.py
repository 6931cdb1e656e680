"""Property tests on random small systems: every MCP solution is a true solution and lies in the
enumerated (exact, complete) solution set; SLEPc's sufficient condition matches a dense solve."""
import numpy as np
import pytest
import scipy.linalg
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from mpi4py import MPI

from app.analyses.runner import analyse_state
from app.common.stages import Stages
from app.loading.classify import classify
from app.scene.schema import parse_scene
from app.systems.discrete import random_contact_problem


def _scene(mu, analyses):
    return parse_scene({"name": "random", "system": {"type": "two_particles", "k": 1, "m": 1, "phi_deg": 30,
                                                       "signs": [1, 1]},
                        "mu": mu, "analyses": analyses, "settings": {"enumerate_max_slip": 8}})


def _in(sol, ref_set, rtol=1e-6):
    return any(abs(sol.value - r.value) <= rtol * max(1.0, abs(r.value))
               and np.allclose(sol.x_Ts, r.x_Ts, atol=1e-5) and sol.pattern == r.pattern
               for r in ref_set)


problems = st.tuples(st.integers(0, 2**31 - 1), st.integers(1, 6), st.integers(0, 2), st.integers(0, 2),
                     st.integers(0, 6), st.floats(0.3, 4.0))


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(problems)
def test_mcp_solutions_are_true_and_enumerated(p):
    seed, n_slip, n_stick, n_free, n_int, mu = p
    rng = np.random.default_rng(seed)
    system, state = random_contact_problem(rng, n_slip + n_stick + n_free, n_int, n_slip, n_stick, mu,
                                           MPI.COMM_WORLD, Stages())
    scene = _scene(mu, ["mceip_mu", "mceip_lambda2", "enumerate"])
    cls = classify(state, mu)
    assert cls.counts()["slip"] == n_slip
    a = analyse_state(system, cls, scene)
    tol = scene.settings.mcp.accept_tol
    for key, prob in (("mceip_mu", "mu"), ("mceip_lambda2", "lambda2")):
        ref = a["enumerate"].problems[prob]
        assert ref.complete
        for sol in a[key].solutions:
            ev = sol.evidence
            assert sol.value >= 0
            assert ev["residual"] <= tol and ev["complementarity"] <= tol
            assert ev["min_x_Ts"] >= -tol and ev["min_y_Ts"] >= -tol
            assert abs(sum(sol.x_Ts) - 1) < 1e-10
            assert _in(sol, ref.solutions), (key, sol, ref.solutions)
    system.destroy()


@pytest.mark.parametrize("seed", range(8))
def test_sufficient_matches_dense_reference(seed):
    """(17)-(18) from SLEPc against scipy.linalg.eig on the same dense pencil."""
    from app.analyses.conditions.full_size import sufficient
    from app.analyses.pencils.reduced import dense, reduced_pencil, reduced_space
    rng = np.random.default_rng(seed)
    mu = 3.0
    system, state = random_contact_problem(rng, 5, 4, 3, 1, mu, MPI.COMM_WORLD, Stages())
    cls = classify(state, mu)
    space = reduced_space(system, cls)
    K0, K1 = reduced_pencil(system.K, system, cls, space)
    M0, M1 = reduced_pencil(system.mass(), system, cls, space)
    Ks = K0.copy(); Ks.axpy(mu, K1)
    Ms = M0.copy(); Ms.axpy(mu, M1)
    out = sufficient(Ks, Ms, space.comp, _scene(mu, ["sufficient"]).settings.eig)
    Kd, Md = dense(Ks), dense(Ms)
    w, V = scipy.linalg.eig(Kd, Md)
    ref = []
    for th, v in zip(w, V.T):
        if abs(th.imag) <= 1e-8 * abs(th) and -th.real > 0:
            xc = v.real[space.comp]
            xc = xc if xc.sum() >= 0 else -xc
            if xc.min() >= -1e-8 * np.abs(xc).max():
                ref.append(-th.real)
    cand = sorted(c["lambda2"] for c in out.real_candidates)
    ref_all = sorted(-th.real for th in w if abs(th.imag) <= 1e-8 * abs(th) and -th.real > 0)
    assert cand == pytest.approx(ref_all, rel=1e-9)
    assert sorted(out.lambda2) == pytest.approx(sorted(ref), rel=1e-9)
    system.destroy()
