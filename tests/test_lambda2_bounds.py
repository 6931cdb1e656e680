"""What MCEIP-lambda^2 results prove (app/analyses/mceip_lambda2/bounds.py), on the paper's two-particle
system (the paper's Fig. 1), where every solution is known in closed form (Table 1)."""
import numpy as np
import pytest
from conftest import run_scene
from test_two_particles import CASES, PHI, K, M, analytic_lambda2, scene

from app.analyses.mceip_lambda2.bounds import inertia_negative_or_zero, proven_upper_bound
from app.analyses.pencils.state import seq_aij


@pytest.mark.parametrize("signs,mu,count", CASES)
def test_certificate_and_bound(signs, mu, count):
    expected = analytic_lambda2(K, M, PHI, mu, *signs)
    a = run_scene(scene(signs, mu, ["necessary", "mceip_lambda2"]))["states"][0]["analyses"]
    l2 = a["mceip_lambda2"]
    cert = l2["certificate"]
    assert set(cert) == {"method", "interval", "status", "gap", "seconds", "detail", "rigorous"}
    if not a["necessary"]["satisfied"]:
        # (19) fails: no solution, proven (K* and M* PD by verified Cholesky: rigorous)
        assert l2["certified"] is True and cert["status"] == "proven" and not expected
        assert cert["interval"] == [0.0, float("inf")] and cert["rigorous"] is True
    elif l2["certified"]:
        # shown on the exact slip-node reduction (app/analyses/mceip_lambda2/exact.py): no solution at
        # all; the reduction's eigen-decomposition is floating point, so not rigorous
        assert cert["status"] == "proven" and cert["interval"] == [0.0, float("inf")] and not expected
        assert cert["rigorous"] is False
        assert not l2["solutions"] and l2["search"]["lambda2_upper_bound"] > 0
    else:
        assert l2["certified"] is False and "not proven" in cert["status"]
        bound = l2["search"]["lambda2_upper_bound"]
        # the proven bound is a bound: every exact solution lies below it, and it is no worse
        # than the Rayleigh-quotient bound it starts from
        assert all(v < bound for v, _, _ in expected)
        ub = l2["search"]["upper_bound"]
        if "rayleigh_bound" in ub:
            assert bound <= ub["rayleigh_bound"]
        for sol in l2["solutions"]:
            assert sol["certified"] is False and sol["ill_conditioned"] is False
            assert sol["pattern_verified"] is True


def test_inertia_count_and_bound_on_a_known_pencil():
    """sym K + T sym M PD exactly for T > 3 (K = diag(-3, 1), M = I): the proven bound brackets 3."""
    Km, Mm = seq_aij(np.diag([-3.0, 1.0])), seq_aij(np.eye(2))
    try:
        assert inertia_negative_or_zero(Km) == 1
        assert inertia_negative_or_zero(Mm) == 0
        T, detail = proven_upper_bound(Km, Mm, 10.0, steps=12)
        assert 3.0 < T <= 3.0 + 10.0 / 2 ** 11
        assert detail["inertia_counts"] >= 12
    finally:
        Km.destroy()
        Mm.destroy()
