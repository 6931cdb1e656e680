"""The finite element block: the paper's numbers, and the contact solver against independent facts."""
import copy

import numpy as np
import pytest
import yaml
from conftest import run_scene

from app.scene.schema import default_scene_path

DEFAULT = yaml.safe_load(default_scene_path().read_text())


def scene(**changes):
    d = copy.deepcopy(DEFAULT)
    for key, value in changes.items():
        if key in ("system", "loading"):
            d[key].update(value)
        else:
            d[key] = value
    return d


@pytest.fixture(scope="module")
def paper():
    """The paper study with MCEIP-mu only (the slow analyses are tested elsewhere)."""
    return run_scene(scene(analyses=["mceip_mu"]))


def _counts(state):
    c = state["classification"]
    return c["stick"], c["slip"], c["free"]


def test_normal_force_reached(paper):
    normal = [s for s in paper["states"] if s["load"]["phase"] == "normal"]
    assert len(normal) == DEFAULT["loading"]["normal_steps"]
    assert normal[-1]["load"]["normal_resultant"] == pytest.approx(55.0, rel=1e-8)
    # the normal resultant grows monotonically while pressing
    assert np.all(np.diff([s["load"]["normal_resultant"] for s in normal]) > 0)


def test_paper_numbers(paper):
    states = [s for s in paper["states"] if s["load"]["phase"] == "tangential"]
    with_sol = [s for s in states if s["analyses"]["mceip_mu"]["solutions"]]
    # MCEIP-mu first has a solution when 11 nodes slip
    assert _counts(with_sol[0])[1] == 11
    assert all(_counts(s)[1] < 11 for s in states[:states.index(with_sol[0])])
    # the values fall as slip spreads: smallest value per number of slip nodes decreases
    by_slip = {}
    for s in with_sol:
        v = min(x["value"] for x in s["analyses"]["mceip_mu"]["solutions"])
        by_slip[_counts(s)[1]] = min(v, by_slip.get(_counts(s)[1], np.inf))
    ks = sorted(by_slip)
    assert all(by_slip[a] > by_slip[b] for a, b in zip(ks, ks[1:]))
    # 2 stuck, 15 slip, 4 free: the single solution 60.81 keeps the fourth node from A stuck
    target = [s for s in states if _counts(s) == (2, 15, 4)]
    assert target
    for s in target:
        sols = s["analyses"]["mceip_mu"]["solutions"]
        assert len(sols) == 1
        assert sols[0]["value"] == pytest.approx(60.81, rel=5e-3)
        slip_nodes = [n["id"] for n in s["nodes"] if n["status"] == "slip"]
        stuck_in_mode = [slip_nodes[i] for i, p in enumerate(sols[0]["pattern"]) if p == "stick"]
        assert stuck_in_mode == [3]  # node ids count from A = 0
    # the final state: 17 slip, 4 free, all-slip mode at mu = 1.705 (paper: 1.71)
    final = paper["states"][-1]
    assert _counts(final) == (0, 17, 4)
    assert "gross sliding" in paper["path"]["end"]
    sols = final["analyses"]["mceip_mu"]["solutions"]
    assert len(sols) == 1 and sols[0]["pattern"] == ["slip"] * 17
    assert sols[0]["value"] == pytest.approx(1.705, rel=5e-3)
    # every reported solution carries its evidence
    for s in with_sol:
        for x in s["analyses"]["mceip_mu"]["solutions"]:
            assert x["residual"] < 1e-8 and x["complementarity"] < 1e-8 and x["found_by"]


def test_signorini_and_coulomb_at_every_node(paper):
    mu = DEFAULT["mu"]
    for s in paper["states"]:
        r_scale = max(abs(n["r_N"]) for n in s["nodes"])
        u_scale = max(max(abs(n["u_N"]), abs(n["u_T"])) for n in s["nodes"])
        for n in s["nodes"]:
            assert n["u_N"] <= 1e-12 * u_scale
            assert n["r_N"] <= 1e-12 * r_scale
            assert abs(n["u_N"] * n["r_N"]) <= 1e-12 * u_scale * r_scale
            assert abs(n["r_T"]) <= mu * -n["r_N"] + 1e-12 * r_scale
        assert s["contact_solve"]["violation"] < 1e-9


def test_classifications_are_shared(paper):
    keys = {s["analyses_shared_with"] for s in paper["states"]}
    assert paper["distinct_classifications"] < len(paper["states"]) / 5
    assert None in keys


def _direct_reactions(clamp_tangential: bool, gx: float, gy: float):
    """Independent reference: the block with AB held by Dirichlet conditions (rollers, or
    clamped), solved directly (dense) from the DOLFINx stiffness; reactions in paper axes."""
    from mpi4py import MPI

    from app.analyses.pencils.reduced import dense, gather_vec
    from app.common.stages import Stages
    from app.scene.schema import parse_scene
    from app.systems.block.path import build_block_system
    cfg = parse_scene(scene()).system
    system, ops, flex = build_block_system(cfg, MPI.COMM_WORLD, Stages())
    K = dense(ops.K)
    f = gx * gather_vec(ops.load_x) + gy * gather_vec(ops.load_y)
    held = list(ops.contact_dof_y) + (list(ops.contact_dof_x) if clamp_tangential else [])
    free = np.setdiff1d(np.arange(K.shape[0]), held)
    u = np.zeros(K.shape[0])
    u[free] = np.linalg.solve(K[np.ix_(free, free)], f[free])
    R = K @ u - f
    system.destroy()
    return R[ops.contact_dof_x], -R[ops.contact_dof_y]   # r_T = R_x, r_N = -R_y


def test_frictionless_limit_equals_rollers():
    """mu = 0 while every node stays in contact: the reactions are those of rollers on AB."""
    res = run_scene(scene(mu=0.0, analyses=[], loading={"tangential_max": 0.02}))
    s = [x for x in res["states"] if x["load"]["phase"] == "normal"][-1]
    assert s["classification"]["free"] == 0
    rT_ref, rN_ref = _direct_reactions(False, s["load"]["u_x"], s["load"]["u_y"])
    rN = np.array([n["r_N"] for n in s["nodes"]])
    assert rN == pytest.approx(rN_ref, rel=1e-8, abs=1e-10 * 55)
    assert np.max(np.abs([n["r_T"] for n in s["nodes"]])) < 1e-9 * 55
    assert np.max(np.abs(rT_ref)) < 1e-9 * 55
    assert rN == pytest.approx(rN[::-1], rel=1e-8)  # symmetric pressing


def test_sticking_limit_equals_clamped_contact_side():
    """A huge mu: nothing slips, and the reactions are those of AB clamped (while in contact)."""
    res = run_scene(scene(mu=1e6, analyses=[], loading={"tangential_max": 1.0}))
    for s in res["states"]:
        assert s["classification"]["slip"] == 0
    s = [x for x in res["states"] if x["classification"]["free"] == 0][-1]
    assert s["load"]["phase"] == "tangential" and s["load"]["u_x"] < 0
    rT_ref, rN_ref = _direct_reactions(True, s["load"]["u_x"], s["load"]["u_y"])
    assert np.array([n["r_N"] for n in s["nodes"]]) == pytest.approx(rN_ref, rel=1e-8, abs=1e-10 * 55)
    assert np.array([n["r_T"] for n in s["nodes"]]) == pytest.approx(rT_ref, rel=1e-8, abs=1e-10 * 55)


def test_mu_values_do_not_depend_on_E(paper):
    # Ten times stiffer: the same forces need a tenth of the displacements, so the tangential
    # steps are scaled too; the path, the classifications and the mu values must not change.
    other = run_scene(scene(analyses=["mceip_mu"], system={"E": 50.0},
                            loading={"tangential_step": 0.002, "tangential_max": 1.0}))
    assert len(other["states"]) == len(paper["states"])
    for a, b in zip(paper["states"], other["states"]):
        assert [n["status"] for n in a["nodes"]] == [n["status"] for n in b["nodes"]]
        # the proven part (every value up to the cap) is the same; values above the cap come
        # from the search only and are not part of the comparison
        ma, mb = a["analyses"]["mceip_mu"], b["analyses"]["mceip_mu"]
        assert ma["onset"]["proven"] and mb["onset"]["proven"]
        assert ma["certified"] == mb["certified"]
        if ma["onset"]["value"] is not None:
            assert ma["onset"]["value"] == pytest.approx(mb["onset"]["value"], rel=1e-8)
        va = [x["value"] for x in ma["solutions"] if x["certified"]]
        vb = [x["value"] for x in mb["solutions"] if x["certified"]]
        assert va == pytest.approx(vb, rel=1e-8)
        # the same forces
        assert b["load"]["normal_resultant"] == pytest.approx(a["load"]["normal_resultant"], rel=1e-8)


def test_condensed_mu_agrees_with_full_size_mcp():
    """Exact condensation onto the slip nodes against the full-size MCP (coarser mesh)."""
    base = dict(system={"nx": 10, "ny": 5}, analyses=["mceip_mu"])
    a = run_scene(scene(**base))
    b = run_scene(scene(**base, settings={"mceip_mu_method": "full"}))
    n_compared = 0
    for sa, sb in zip(a["states"], b["states"]):
        # the condensed answer is certified (complete below the cap); the full-size SNES VI
        # search is a search: everything it finds is in the condensed set, with the same value
        x = sorted((v["value"], v["pattern"]) for v in sa["analyses"]["mceip_mu"]["solutions"])
        y = sorted((v["value"], v["pattern"]) for v in sb["analyses"]["mceip_mu"]["solutions"])
        for v, p in y:
            assert any(p == q and v == pytest.approx(w, rel=1e-8) for w, q in x), (v, p, x)
        n_compared += len(y)
    assert n_compared > 0


def test_equilibrium_of_resultants_with_the_reactions(paper):
    """Rebuild whole fields from the reported reactions and assemble the internal forces with
    DOLFINx: they vanish at interior nodes, equal the reactions on AB, and the force on CD
    balances the resultants of the reactions."""
    import dolfinx.fem
    import dolfinx.fem.petsc
    import ufl
    from mpi4py import MPI

    from app.common.stages import Stages
    from app.scene.schema import parse_scene
    from app.systems.block.path import build_block_system
    from app.systems.elasticity import lame_parameters
    cfg = parse_scene(scene()).system
    system, ops, flex = build_block_system(cfg, MPI.COMM_WORLD, Stages())
    V = ops.V
    mu_l, lam = lame_parameters(cfg.E, cfg.nu, cfg.plane)
    u = dolfinx.fem.Function(V)
    v = ufl.TestFunction(V)
    eps = ufl.sym(ufl.grad(u))
    sigma = 2 * mu_l * eps + lam * ufl.tr(eps) * ufl.Identity(2)
    form = dolfinx.fem.form(cfg.thickness * ufl.inner(sigma, ufl.sym(ufl.grad(v))) * ufl.dx)
    coords = V.tabulate_dof_coordinates()
    n_own = V.dofmap.index_map.size_local
    on_ab = np.isclose(coords[:n_own, 1], 0.0)
    on_cd = np.isclose(coords[:n_own, 1], cfg.height)
    inside = ~(on_ab | on_cd)
    picks = [paper["states"][9], paper["states"][150], paper["states"][-1]]
    for st in picks:
        r = np.ravel([[n["r_T"], n["r_N"]] for n in st["nodes"]])
        uh = flex.field(st["load"]["u_x"], st["load"]["u_y"], r)
        u.x.array[:] = ops.to_function(uh, st["load"]["u_x"], st["load"]["u_y"]).x.array
        f = dolfinx.fem.petsc.assemble_vector(form)
        f.ghostUpdate(addv=PETSc_ADD(), mode=PETSc_REVERSE())
        fa = f.getArray().reshape(-1, 2)[:n_own]
        scale = st["load"]["normal_resultant"]
        assert np.max(np.abs(fa[inside])) < 1e-9 * scale
        # internal force on AB = reaction (R_x = r_T, R_y = -r_N), sorted by x
        order = np.argsort(coords[:n_own][on_ab, 0])
        R = fa[on_ab][order]
        assert R[:, 0] == pytest.approx([n["r_T"] for n in st["nodes"]], abs=1e-9 * scale)
        assert R[:, 1] == pytest.approx([-n["r_N"] for n in st["nodes"]], abs=1e-9 * scale)
        # the force transmitted through CD balances the resultants on AB
        F_cd = fa[on_cd].sum(axis=0)
        assert F_cd[0] == pytest.approx(-st["load"]["tangential_resultant"], rel=1e-9)
        assert F_cd[1] == pytest.approx(-st["load"]["normal_resultant"], rel=1e-9)
        f.destroy()
        uh.destroy()
    system.destroy()


def PETSc_ADD():
    from petsc4py import PETSc
    return PETSc.InsertMode.ADD


def PETSc_REVERSE():
    from petsc4py import PETSc
    return PETSc.ScatterMode.REVERSE


def test_paper_study_is_certified(paper):
    """Every distinct classification of the paper study has a proven MCEIP-mu onset (re-verified
    by the checker), the list below the cap wherever it is claimed, and the proven onsets are the
    paper's figures."""
    listed = 0
    for s in paper["states"]:
        m = s["analyses"]["mceip_mu"]
        assert m["onset"]["proven"], (s["index"], m["certificate"])
        if m["certified"]:
            listed += 1
            assert m["certificate"]["status"] == "proven"
            for x in m["solutions"]:
                assert x["certified"] == (x["value"] <= m["certificate"].get("cap", np.inf))
        else:
            assert not any(x["certified"] for x in m["solutions"])
    assert listed >= len(paper["states"]) // 2
    final = paper["states"][-1]["analyses"]["mceip_mu"]
    assert final["certificate"]["onset"] == pytest.approx(1.7048, abs=1e-4)
