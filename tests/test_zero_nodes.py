"""Zero-reaction contact nodes (the paper's set Z) through the rate conditions (9), against enumeration."""
import numpy as np
import pytest
from mpi4py import MPI

from app.analyses.enumerate import enumerate_mceip
from app.analyses.outcomes import Failed
from app.analyses.pencils.reduced import condensed_mu_pencil, dense, reduced_pencil, reduced_space, split_pencils
from app.analyses.runner import analyse_state
from app.common.stages import Stages
from app.loading.classify import classify
from app.scene.schema import parse_scene
from app.systems.discrete import random_contact_problem


def _scene(mu, analyses):
    return parse_scene({"name": "z", "mu": mu, "analyses": analyses, "mceip_lambda2_mu": mu,
                        "system": {"type": "two_particles", "k": 1, "m": 1, "phi_deg": 30, "signs": [1, 1]},
                        "settings": {"enumerate_max_slip": 12}})


def _key(sols):
    return sorted((round(x["value"], 7), tuple(x["pattern"])) for x in sols)


@pytest.mark.parametrize("seed", range(6))
def test_split_pencil_without_zero_nodes_matches_the_reduced_pencils(seed):
    """The general R A Q construction reproduces (10)-(16) when Z is empty."""
    rng = np.random.default_rng(seed)
    mu = 2.0
    system, state = random_contact_problem(rng, 6, 5, 3, 1, mu, MPI.COMM_WORLD, Stages())
    cls = classify(state, mu)
    sp = split_pencils(system, cls)
    A0, A1 = condensed_mu_pencil(system.contact_schur(), cls)
    assert np.allclose(sp.A0, A0) and np.allclose(sp.A1, A1)
    space = reduced_space(system, cls)
    K0, K1 = (dense(m) for m in reduced_pencil(system.K, system, cls, space))
    full = split_pencils(system, cls, dense(system.K))
    ref = enumerate_mceip(K0, K1, space.comp, 12)
    got = enumerate_mceip(full.A0, full.A1, full.comp, 12)
    assert _key(ref) == _key(got)
    system.destroy()


def _with_zero_node(seed, n_slip=2, n_zero=1, mu=2.0):
    rng = np.random.default_rng(seed)
    system, state = random_contact_problem(rng, n_slip + n_zero + 2, 5, n_slip, 1, mu, MPI.COMM_WORLD, Stages())
    free = [i for i in range(len(state.r_N)) if state.r_N[i] == 0][:n_zero]
    state.u_N[free] = 0.0          # in contact, zero reaction
    cls = classify(state, mu)
    assert cls.counts()["zero"] == n_zero
    return system, cls


@pytest.mark.parametrize("seed", range(12))
def test_zero_node_mcp_solutions_are_enumerated(seed):
    mu = 2.0
    system, cls = _with_zero_node(seed, mu=mu)
    a = analyse_state(system, cls, _scene(mu, ["mceip_mu", "mceip_lambda2", "enumerate", "necessary"]))
    assert isinstance(a["necessary"], Failed) and "zero-reaction" in a["necessary"].reason
    for key, prob in (("mceip_mu", "mu"), ("mceip_lambda2", "lambda2")):
        ref = a["enumerate"].problems[prob].solutions
        for sol in a[key].solutions:
            assert sol.evidence["residual"] < 1e-8 and sol.evidence["complementarity"] < 1e-8
            zn = sol.evidence["zero_nodes"][0]
            assert min(zn["a"], zn["b"]) == 0.0          # canonical split of v_T
            assert any(abs(sol.value - r.value) <= 1e-6 * max(1, r.value)
                       and np.allclose(list(sol.evidence["x_c"].values()), list(r.evidence["x_c"].values()), atol=1e-5)
                       for r in ref), (key, sol, ref)
    system.destroy()


def test_zero_node_search_finds_the_enumerated_solutions():
    """Over several random systems with a zero-reaction node the search finds what enumeration proves."""
    total = found = 0
    for seed in range(12):
        system, cls = _with_zero_node(seed)
        a = analyse_state(system, cls, _scene(2.0, ["mceip_mu", "enumerate"]))
        ref = a["enumerate"].problems["mu"].solutions
        # below the cap the answer is certified: every enumerated value is there
        assert a["mceip_mu"].certified
        cap = a["mceip_mu"].certificate.interval[1]
        ref = [r for r in ref if r.value <= cap]
        total += len(ref)
        found += sum(any(abs(s.value - r.value) <= 1e-6 * max(1, r.value) for s in a["mceip_mu"].solutions)
                     for r in ref)
        system.destroy()
    assert total > 0
    assert found == total, (found, total)
