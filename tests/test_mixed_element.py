"""The mixed (Taylor-Hood P2-P1 displacement-pressure) element, ``system.element: mixed``.

- Patch test of the mixed operator (app/systems/stress.py ``mixed_forms``): a linear displacement
  and its constant pressure solve the discrete equations exactly on a distorted mesh, for a
  compressible and the incompressible material.
- Closed form through the whole app: a strip pressed on a frictionless rigid line, its top moved
  down until the normal force is F, its left side held in x on its upper half; the uniform state
  ``sigma_yy = -F / (L t)``, ``sigma_xx = 0`` gives the depth ``F H (1 - nu^2) / (E L t)`` (plane
  strain), exactly (a linear field), nu = 1/2 included.
- The compressible limit: at nu = 0.3 the mixed element and P2 displacements converge to the same
  values; nu = 1/2 runs and converges; one-line refusals.
- The analyses that read eigenvalues ((19), (17)-(18), MCEIP-lambda^2) equal those of the
  displacement-only system built in the test by eliminating the pressure.
"""
import math
import pathlib

import numpy as np
import pytest
import yaml
from conftest import run_cli_here, run_scene

STRIP = """
L = 40; H = 10;
Point(1) = {0, 0, 0}; Point(2) = {L, 0, 0}; Point(3) = {L, H, 0}; Point(4) = {0, H, 0}; Point(5) = {0, H / 2, 0};
Line(1) = {1, 2}; Line(2) = {2, 3}; Line(3) = {3, 4}; Line(4) = {4, 5}; Line(5) = {5, 1};
Curve Loop(1) = {1, 2, 3, 4, 5}; Plane Surface(1) = {1};
Mesh.CharacteristicLengthMax = 2.5;
Physical Curve("bottom") = {1}; Physical Curve("top") = {3}; Physical Curve("roller") = {4};
Physical Surface("strip") = {1};
"""


def test_patch_test_of_the_mixed_operator():
    """u = A x + b, p = kappa tr(A) (compressible) or any constant (incompressible, tr A = 0): the
    mixed equations hold exactly with the boundary tractions of that uniform stress."""
    import dolfinx.fem
    import dolfinx.fem.petsc
    import dolfinx.mesh
    import ufl
    from mpi4py import MPI
    from petsc4py import PETSc

    from app.systems.elasticity import bulk_compliance
    from app.systems.stress import mixed_forms, mixed_stress
    mesh = dolfinx.mesh.create_unit_square(MPI.COMM_SELF, 5, 4, dolfinx.mesh.CellType.triangle)
    x = mesh.geometry.x
    x[:, :2] += 0.03 * np.sin(7.0 * x[:, [1, 0]])          # a distorted mesh (edges stay straight)
    V = dolfinx.fem.FunctionSpace(mesh, ufl.VectorElement("CG", mesh.ufl_cell(), 2))
    Q = dolfinx.fem.FunctionSpace(mesh, ("CG", 1))
    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    p, q = ufl.TrialFunction(Q), ufl.TestFunction(Q)
    E, t = 5.0, 1.5
    for nu, A in ((0.3, np.array([[0.02, 0.013], [-0.004, -0.011]])),
                  (0.5, np.array([[0.02, 0.013], [-0.004, -0.02]]))):
        mu = E / (2 * (1 + nu))
        inv_kappa = bulk_compliance(E, nu, "strain")
        p_exact = np.trace(A) / inv_kappa if inv_kappa > 0 else 0.37
        const = lambda c: dolfinx.fem.Constant(mesh, PETSc.ScalarType(c))    # noqa: E731 - (0 stays a form)
        a = [[dolfinx.fem.form(f) for f in row] for row in mixed_forms(u, p, v, q, const(mu), const(inv_kappa), t)]
        K = dolfinx.fem.petsc.assemble_matrix_block(a)
        K.assemble()
        uex = dolfinx.fem.Function(V)
        uex.interpolate(lambda X: np.vstack([A[0, 0] * X[0] + A[0, 1] * X[1] + 0.1, A[1, 0] * X[0] + A[1, 1] * X[1]]))
        pex = dolfinx.fem.Function(Q)
        pex.x.array[:] = p_exact
        n = ufl.FacetNormal(mesh)
        sigma = mixed_stress(uex, pex, mu)
        L_u = dolfinx.fem.form(t * ufl.inner(sigma * n, v) * ufl.ds)      # the boundary tractions
        L_p = dolfinx.fem.form(dolfinx.fem.Constant(mesh, PETSc.ScalarType(0.0)) * q * ufl.dx)
        b = dolfinx.fem.petsc.assemble_vector_block([L_u, L_p], a)
        x_exact = K.createVecRight()
        nV = V.dofmap.index_map.size_local * 2
        x_exact.getArray()[:nV] = uex.x.array[:nV]
        x_exact.getArray()[nV:] = pex.x.array[:Q.dofmap.index_map.size_local]
        r = b.duplicate()
        K.mult(x_exact, r)
        r.axpy(-1.0, b)
        assert r.norm() <= 1e-12 * b.norm(), (nu, r.norm(), b.norm())
        for obj in (K, b, r, x_exact):
            obj.destroy()


def _strip_scene(tmp_path: pathlib.Path, element: str, degree: int, nu: float) -> pathlib.Path:
    (tmp_path / "strip.geo").write_text(STRIP)
    scene = {"name": "strip", "mu": 0.0, "analyses": ["mceip_mu"],
             "system": {"type": "gmsh", "file": "strip.geo", "contact": "bottom", "prescribed": {"top": "y", "roller": "x"},
                        "material": {"E": 5.0, "nu": nu}, "degree": degree, "element": element, "plane": "strain",
                        "thickness": 2.0,
                        "program": [{"name": "press", "steps": 2, "until": {"normal_force": 30.0},
                                     "displacement": {"top": {"translation": [0.0, -1.0]}}}]}}
    (tmp_path / "strip.yaml").write_text(yaml.safe_dump(scene))
    return tmp_path / "strip.yaml"


@pytest.mark.parametrize("element, degree, nu", [("mixed", 2, 0.5), ("mixed", 2, 0.3), ("mixed", 2, 0.499),
                                                 ("displacement", 2, 0.3), ("displacement", 1, 0.3)])
def test_a_pressed_strip_has_the_closed_form_depth(tmp_path, element, degree, nu):
    import json
    f = _strip_scene(tmp_path, element, degree, nu)
    p = run_cli_here("run", str(f), "-o", str(tmp_path / "o"), "-q")
    assert p.returncode == 0, p.stderr
    res = json.loads((tmp_path / "o" / "results.json").read_text())
    final = res["states"][-1]
    E, L, H, t, F = 5.0, 40.0, 10.0, 2.0, 30.0
    depth = F * H * (1 - nu * nu) / (E * L * t)
    assert -final["load"]["parameters"]["motion.top.ty"] == pytest.approx(depth, rel=1e-10)
    assert sum(n["r_N"] for n in final["nodes"]) == pytest.approx(-F, rel=1e-12)
    assert all(n["status"] != "free" for n in final["nodes"])
    if element == "mixed":
        assert "P2-P1 mixed" in res["system"]


def _block(nx: int, element: str, nu: float, **extra) -> dict:
    # the onsets the search finds (their proofs, which these tests do not compare, cost most of the time)
    return {"name": "b", "mu": 1.1, "analyses": ["mceip_mu"], "settings": {"mcp": {"certify": False}},
            "loading": {"normal_force": 55.0, "normal_steps": 10, "tangential_step": 0.05, "tangential_max": 10.0},
            "system": {"type": "block", "nx": nx, "ny": nx // 2, "degree": 2, "element": element, "plane": "strain",
                       "nu": nu, **extra}}


def _final_mu(res) -> float:
    return min(s["value"] for s in res["states"][-1]["analyses"]["mceip_mu"]["solutions"])


def test_the_compressible_limit_agrees_with_p2_displacements():
    """nu = 0.3, plane strain: the depth for 55 N and the last state's smallest critical mu of the
    mixed element and of P2 displacements approach each other under refinement."""
    gaps_depth, gaps_mu = [], []
    for nx in (10, 20, 40):
        a, b = run_scene(_block(nx, "mixed", 0.3)), run_scene(_block(nx, "displacement", 0.3))
        gaps_depth.append(abs(a["states"][9]["load"]["u_y"] - b["states"][9]["load"]["u_y"]))
        gaps_mu.append(abs(_final_mu(a) - _final_mu(b)))
    print(f"nu = 0.3, mixed against P2: depth differences {gaps_depth}, final mu differences {gaps_mu}")
    assert gaps_depth[2] < gaps_depth[1] < gaps_depth[0]
    assert gaps_depth[2] < 1e-4 * 0.47
    assert gaps_mu[2] < gaps_mu[0] and gaps_mu[2] < 2e-3


def test_the_incompressible_block_runs_and_its_onset_converges():
    """nu = 1/2 exactly, plane strain, mixed: a finite critical mu at the last state, and the
    differences between successive meshes shrink."""
    mus = [_final_mu(run_scene(_block(nx, "mixed", 0.5))) for nx in (10, 20, 40)]
    print(f"nu = 1/2: final mu {mus}")
    assert all(math.isfinite(m) and m > 0 for m in mus)
    assert abs(mus[2] - mus[1]) < abs(mus[1] - mus[0])


@pytest.mark.parametrize("system, key, words", [
    ({"type": "block", "element": "mixed", "degree": 1}, "system.element", "give degree: 2"),
    ({"type": "block", "nu": 0.5}, "system.nu", "needs element: mixed"),
    ({"type": "block", "nu": 0.51, "element": "mixed", "degree": 2}, "system.nu", "0.5"),
    ({"type": "block", "element": "hybrid"}, "system.element", "mixed"),
])
def test_element_keys_are_checked_in_one_line(tmp_path, system, key, words):
    (tmp_path / "s.yaml").write_text(yaml.safe_dump({"name": "e", "mu": 1.1, "analyses": ["mceip_mu"], "system": system}))
    p = run_cli_here("validate", str(tmp_path / "s.yaml"))
    line = p.stderr.strip()
    assert p.returncode == 2 and len(line.splitlines()) == 1 and key in line and words in line, line


@pytest.mark.parametrize("name", ["block_incompressible.yaml", "block_plane_strain_mixed.yaml", "refinement_mixed.yaml"])
def test_the_shipped_mixed_scenes_validate(name):
    root = pathlib.Path(__file__).resolve().parents[1]
    p = run_cli_here("validate", str(root / "app" / "scenes" / name), cwd="/")
    assert p.returncode == 0, p.stderr


@pytest.mark.parametrize("nu", [0.45, 0.499])
def test_the_necessary_condition_is_that_of_the_system_with_the_pressure_eliminated(nu):
    """(19) with the mixed element (app/analyses/conditions/contact_spectrum.py with the pressure
    eliminated first) against LAPACK on the reduced pencils of the eliminated system built here:
    K_e = K_uu - K_up K_pp^-1 K_pu and M_u as a discrete system with the same contact nodes (stick,
    slip both ways, free and mixed classifications, three mu). Symmetrising and eliminating do not
    commute once K*(mu) is not symmetric, so the all-slip cases tell the right order from the wrong."""
    from mpi4py import MPI
    from test_contact_spectrum import _cases

    from app.analyses.conditions import contact_spectrum as cs
    from app.analyses.pencils.reduced import combine, dense
    from app.analyses.pencils.state import StatePencils
    from app.common.stages import Stages
    from app.scene.schema import parse_scene
    from app.systems.base import ContactNode
    from app.systems.block.path import build
    from app.systems.discrete import discrete_system
    scene = {"name": "m", "mu": 1.1, "analyses": ["necessary"],
             "system": {"type": "block", "nx": 6, "ny": 3, "degree": 2, "element": "mixed", "plane": "strain", "nu": nu}}
    with build(parse_scene(scene).system, MPI.COMM_WORLD, Stages()) as system:
        K, M = dense(system.K), dense(system.mass())
        st = system.static_dofs
        keep = np.setdiff1d(np.arange(K.shape[0]), st)
        assert len(st) > 0 and np.abs(M[np.ix_(st, st)]).max() == 0.0
        Ke = K[np.ix_(keep, keep)] - K[np.ix_(keep, st)] @ np.linalg.solve(K[np.ix_(st, st)], K[np.ix_(st, keep)])
        nodes = [ContactNode(id=nd.id, x=nd.x, dof_T=int(np.searchsorted(keep, nd.dof_T)),
                             dof_N=int(np.searchsorted(keep, nd.dof_N)), sign_T=nd.sign_T, sign_N=nd.sign_N)
                 for nd in system.nodes]
        spectra = cs.contact_spectra(system)
        assert spectra is not None
        slip_cases = 0
        with discrete_system(Ke, M[np.ix_(keep, keep)], nodes, MPI.COMM_SELF, Stages(), system.units, "eliminated") as ref:
            for cls in _cases(len(nodes)):
                for mu in (0.3, 1.1, 3.0):
                    p = StatePencils(ref, cls)
                    try:
                        for sc, (A0, A1) in zip(spectra, (p.K(), p.M())):
                            A = dense(combine(A0, A1, mu))
                            A = 0.5 * (A + A.T)
                            lam = np.linalg.eigvalsh(A)[0]
                            v = cs.value(sc, cls, mu)
                            assert v is not None, (cls.counts(), mu)
                            assert abs(v.value - lam) <= 1e-9 * np.abs(np.diag(A)).max(), (cls.counts(), mu, v.value, lam)
                    finally:
                        p.destroy()
                    slip_cases += len(cls.slip) > 0
        assert slip_cases >= 9


def test_the_necessary_condition_at_nu_one_half_is_refused_in_one_line(tmp_path):
    (tmp_path / "s.yaml").write_text(yaml.safe_dump({
        "name": "e", "mu": 1.1, "analyses": ["necessary", "mceip_mu"],
        "system": {"type": "block", "degree": 2, "element": "mixed", "plane": "strain", "nu": 0.5}}))
    p = run_cli_here("validate", str(tmp_path / "s.yaml"))
    line = p.stderr.strip()
    assert p.returncode == 2 and len(line.splitlines()) == 1 and "system.nu = 0.5" in line and "necessary" in line, line


@pytest.mark.parametrize("nx", [6, 8])
def test_the_sufficient_condition_and_mceip_lambda2_at_nu_one_half(nx):
    """nu = 1/2 exactly: the pressure is a constraint. The sufficient condition (17)-(18) (6 x 3: on
    the constraint's kernel, every eigenvalue; 8 x 4: SLEPc's shift-and-invert with pivoting) against
    the QZ algorithm on the whole pencil with the pressure (scipy.linalg.eig: its finite eigenvalues;
    the pencil's infinite ones come out above 1e6 of the stiffness-to-mass scale and are left out),
    and MCEIP-lambda^2 (no bound on lambda^2 there: searched) holds every admissible eigenpair."""
    import scipy.linalg
    from mpi4py import MPI
    from test_contact_spectrum import _cases

    from app.analyses.outcomes import MceipLambda2Outcome, SufficientOutcome
    from app.analyses.pencils.reduced import dense
    from app.analyses.pencils.state import StatePencils
    from app.analyses.runner import analyse_state
    from app.common.stages import Stages
    from app.scene.schema import parse_scene
    from app.systems.block.path import build
    scene = parse_scene({"name": "m", "mu": 1.1, "analyses": ["sufficient", "mceip_lambda2"],
                         "system": {"type": "block", "nx": nx, "ny": nx // 2, "degree": 2, "element": "mixed",
                                    "plane": "strain", "nu": 0.5}})
    admissible = 0
    with build(scene.system, MPI.COMM_WORLD, Stages()) as system:
        assert system.static_constraint
        for cls in _cases(len(system.nodes)):
            for mu in (1.1, 3.0):
                got = analyse_state(system, cls, scene.model_copy(update={"mu": mu}))
                suff, lam = got["sufficient"], got["mceip_lambda2"]
                assert isinstance(suff, SufficientOutcome) and isinstance(lam, MceipLambda2Outcome), (cls.counts(), mu)
                if not len(cls.slip):
                    continue
                p = StatePencils(system, cls)
                try:
                    K, M = (dense(A) for A in p.star(mu))
                finally:
                    p.destroy()
                theta = scipy.linalg.eig(K, M, right=False)
                scale = np.abs(np.diag(K)).max() / np.abs(np.diag(M)).max()
                real = np.isfinite(theta) & (np.abs(theta.imag) <= 1e-8 * np.abs(theta)) & (theta.real < 0)
                qz = np.sort(-theta[real & (np.abs(theta) < 1e6 * scale)].real)
                cands = np.sort([c["lambda2"] for c in suff.real_candidates])
                for v in cands:
                    assert np.min(np.abs(qz - v)) <= 1e-7 * v, (cls.counts(), mu, v, qz[:5])
                if nx == 6:                                   # every eigenvalue: the same lists
                    np.testing.assert_allclose(cands, qz, rtol=1e-7)
                for v in suff.lambda2:                        # admissible eigenpairs solve (12)-(14)
                    assert any(abs(s.value - v) <= 1e-7 * v for s in lam.solutions), (cls.counts(), mu, v)
                admissible += len(suff.lambda2)
    assert admissible >= 1


def test_the_transient_dynamics_with_the_mixed_element_is_refused_in_one_line(tmp_path):
    (tmp_path / "s.yaml").write_text(yaml.safe_dump({
        "name": "e", "mu": 1.1, "analyses": ["mceip_lambda2", "mceip_mu"], "transient": {"states": ["final"]},
        "system": {"type": "block", "degree": 2, "element": "mixed", "plane": "strain", "nu": 0.45}}))
    p = run_cli_here("validate", str(tmp_path / "s.yaml"))
    line = p.stderr.strip()
    assert p.returncode == 2 and len(line.splitlines()) == 1 and "transient" in line and "mixed" in line, line


def _eliminated_twin(system):
    """The displacement-only system of a mixed one, built here by dense elimination: K_e = K_uu -
    K_up K_pp^-1 K_pu, the mass M_u, the same contact nodes (DOFs renumbered)."""
    from mpi4py import MPI

    from app.analyses.pencils.reduced import dense
    from app.common.stages import Stages
    from app.systems.base import ContactNode
    from app.systems.discrete import discrete_system
    K, M = dense(system.K), dense(system.mass())
    st = system.static_dofs
    keep = np.setdiff1d(np.arange(K.shape[0]), st)
    Ke = K[np.ix_(keep, keep)] - K[np.ix_(keep, st)] @ np.linalg.solve(K[np.ix_(st, st)], K[np.ix_(st, keep)])
    nodes = [ContactNode(id=nd.id, x=nd.x, dof_T=int(np.searchsorted(keep, nd.dof_T)),
                         dof_N=int(np.searchsorted(keep, nd.dof_N)), sign_T=nd.sign_T, sign_N=nd.sign_N)
             for nd in system.nodes]
    return discrete_system(0.5 * (Ke + Ke.T), M[np.ix_(keep, keep)], nodes, MPI.COMM_SELF, Stages(),
                           system.units, "eliminated")


@pytest.mark.parametrize("nx, exact_max_dofs, mus", [(6, 1500, (0.3, 1.1, 3.0)), (8, 0, (1.1, 3.0))])
def test_the_conditions_and_mceip_lambda2_are_those_of_the_system_with_the_pressure_eliminated(
        nx, exact_max_dofs, mus):
    """The sufficient condition (17)-(18) and MCEIP-lambda^2 (12)-(14) with the mixed element (nu =
    0.45) against the same analyses of the displacement-only system built here by eliminating the
    pressure (:func:`_eliminated_twin`), classification by classification (stick, slip both ways,
    free and mixed ones) at several mu. 6 x 3 (346 DOFs): the dense paths (the sufficient
    condition by LAPACK on the eliminated pencil, MCEIP-lambda^2's reduction from the dense
    eigen-decomposition); 8 x 4 (605 DOFs, ``lambda2_exact_max_dofs: 0``): SLEPc's shift-and-invert
    on the pencil with the pressure and MUMPS's Schur complements of the saddle-point K + t M.
    Proven statuses equal, eigenvalues and solutions to 1e-8; the two meshes between them have
    each kind of answer (proven none, solutions found, the sufficient condition satisfied)."""
    from mpi4py import MPI
    from test_contact_spectrum import _cases

    from app.analyses.outcomes import MceipLambda2Outcome, SufficientOutcome
    from app.analyses.runner import analyse_state
    from app.common.stages import Stages
    from app.scene.schema import parse_scene
    from app.systems.block.path import build
    scene = parse_scene({"name": "m", "mu": 1.1, "analyses": ["necessary", "sufficient", "mceip_lambda2"],
                         "settings": {"mcp": {"lambda2_exact_max_dofs": exact_max_dofs}},
                         "system": {"type": "block", "nx": nx, "ny": nx // 2, "degree": 2, "element": "mixed",
                                    "plane": "strain", "nu": 0.45}})
    seen = set()
    with build(scene.system, MPI.COMM_WORLD, Stages()) as system, _eliminated_twin(system) as ref:
        for cls in _cases(len(system.nodes)):
            for mu in mus:
                at = scene.model_copy(update={"mu": mu})
                got, want = analyse_state(system, cls, at), analyse_state(ref, cls, at)
                where = (cls.counts(), mu)
                a, b = got["sufficient"], want["sufficient"]
                assert isinstance(a, SufficientOutcome) and isinstance(b, SufficientOutcome), where
                assert a.satisfied == b.satisfied and len(a.lambda2) == len(b.lambda2), (where, a.lambda2, b.lambda2)
                np.testing.assert_allclose(a.lambda2, b.lambda2, rtol=1e-8)
                a, b = got["mceip_lambda2"], want["mceip_lambda2"]
                assert isinstance(a, MceipLambda2Outcome) and isinstance(b, MceipLambda2Outcome), where
                assert (a.certified, a.result) == (b.certified, b.result) or not (a.certified or b.certified), \
                    (where, a.result, b.result)
                np.testing.assert_allclose(sorted(x.value for x in a.solutions), sorted(x.value for x in b.solutions),
                                           rtol=1e-8)
                seen.add("proven none" if a.certified and not a.solutions and len(cls.slip) else
                         "found" if a.solutions else "other")
                seen.add("sufficient" if got["sufficient"].satisfied else "not sufficient")
    print(nx, sorted(seen))
    assert {"proven none", "found"} <= seen and (nx == 6 or "sufficient" in seen)


def test_the_four_default_analyses_with_the_mixed_element_on_one_and_two_ranks(tmp_path):
    """The default analyses (necessary, sufficient, MCEIP-mu, MCEIP-lambda^2) along a path of the
    mixed block (nu = 0.48, plane strain): every analysis runs without a failure, every MCEIP-mu
    onset is proven, and two ranks give the answers of one (``benchmarks/compare_results.py``)."""
    import sys

    from conftest import ROOT, results_on_ranks
    sys.path.insert(0, str(ROOT / "benchmarks"))
    from compare_results import answers, compare
    scene = {"name": "b", "mu": 1.1, "outputs": {"plots": False, "report": False, "screenshots": False},
             "loading": {"normal_force": 55.0, "normal_steps": 5, "tangential_step": 0.1, "tangential_max": 10.0},
             "system": {"type": "block", "nx": 8, "ny": 4, "degree": 2, "element": "mixed", "plane": "strain",
                        "nu": 0.48}}
    (tmp_path / "s.yaml").write_text(yaml.safe_dump(scene))
    out = results_on_ranks(tmp_path / "s.yaml", tmp_path)
    one = out[1]
    assert not one["failures"] and set(one["analyses_requested"]) == {"necessary", "sufficient", "mceip_mu", "mceip_lambda2"}
    onsets = [s["analyses"]["mceip_mu"]["onset"] for s in one["states"] if s["analyses"]["mceip_mu"].get("solutions")]
    assert onsets and all(o["proven"] for o in onsets)
    lam = [s["analyses"]["mceip_lambda2"] for s in one["states"]]
    assert all(a["certified"] for a in lam), {a["result"] for a in lam}
    assert not compare(answers(one), answers(out[2]), 1e-8)


def test_the_dense_values_of_the_necessary_condition_equal_the_contact_dofs_ones():
    """Where the contact DOFs decline a classification (a root outside the interpolated pieces) the
    values of (19) with the pressure eliminated come from the dense reduced pencils
    (app/analyses/conditions/eliminated.py ``_dense_eliminated``); on the block both ways
    apply and agree, values and scales, stick, slip, free and mixed classifications at three mu
    (nu = 0.45)."""
    from mpi4py import MPI
    from test_contact_spectrum import _cases

    from app.analyses.conditions import contact_spectrum as cs
    from app.analyses.conditions import eliminated
    from app.analyses.pencils.state import StatePencils
    from app.common.stages import Stages
    from app.scene.schema import parse_scene
    from app.systems.block.path import build
    scene = parse_scene({"name": "m", "mu": 1.1, "analyses": ["necessary"],
                         "system": {"type": "block", "nx": 6, "ny": 3, "degree": 2, "element": "mixed",
                                    "plane": "strain", "nu": 0.45}})
    with build(scene.system, MPI.COMM_WORLD, Stages()) as system:
        for cls in _cases(len(system.nodes)):
            for mu in (0.3, 1.1, 3.0):
                p = StatePencils(system, cls)
                try:
                    dense = eliminated._dense_eliminated(p, mu)
                finally:
                    p.destroy()
                known = cs.values(system, cls, mu, {})
                for name in ("K", "M"):
                    (a, scale), (b, scale_b, _) = dense[name], known[name]
                    assert abs(a - b) <= 1e-9 * scale, (cls.counts(), mu, name, a, b)
                    assert scale == pytest.approx(scale_b, rel=1e-9), (cls.counts(), mu, name, scale, scale_b)


def test_the_mixed_element_on_a_curved_obstacle_runs_every_analysis(tmp_path):
    """The half-disk on a convex cylinder (docs/method.md section 8) with the mixed element (nu =
    0.45, the coarse mesh): the four analyses at every state without a failure, (19) from the
    contact DOFs in the rotated contact frames with the curvature term, MCEIP-lambda^2 decided by
    it where it fails and searched where it holds, every MCEIP-mu onset proven."""
    import json
    root = pathlib.Path(__file__).resolve().parents[1]
    p = run_cli_here("run", str(root / "app/scenes/gmsh/half_disk_cylinder.yaml"), "-o", str(tmp_path / "o"), "-q",
                     "--set", "system.element=mixed", "--set", "system.degree=2", "--set", "system.material.nu=0.45",
                     "--set", "system.mesh_size_factor=2",
                     "--set", "analyses=[necessary,sufficient,mceip_mu,mceip_lambda2]",
                     "--set", "outputs.screenshots=false", "--set", "outputs.plots=false", "--set", "outputs.report=false")
    assert p.returncode == 0, p.stderr
    res = json.loads((tmp_path / "o" / "results.json").read_text())
    assert not res["failures"] and "P2-P1 mixed" in res["system"]
    for st in res["states"]:
        a = st["analyses"]
        assert {"necessary", "sufficient", "mceip_mu", "mceip_lambda2"} <= a.keys()
        if a["mceip_lambda2"]["result"].startswith("no solution (proved by the necessary"):
            assert a["necessary"]["satisfied"] is False
        if a["mceip_mu"].get("solutions"):
            assert a["mceip_mu"]["onset"]["proven"]
