"""``system.type: matrices``: systems given as matrix files (app/systems/matrices*.py).

- the two-particle system of the paper written as files reproduces Table 1 (analytic, as in
  tests/test_two_particles.py) and equals the built-in two_particles scene;
- a random system through files equals the same system built in memory;
- the paper's block exported as matrices (its reduced K and the unit-motion loads of CD as force
  vectors) and loaded by force phases gives the built-in block's path: same classifications,
  same MCEIP-mu;
- one-line errors for user mistakes.
"""

import numpy as np
import pytest
import scipy.io
import scipy.sparse as sp
from conftest import results_on_ranks, run_cli_here, run_scene
from mpi4py import MPI
from test_two_particles import CASES, PHI, analytic_lambda2, analytic_mu, assert_same_set
from test_two_particles import K as KP
from test_two_particles import M as MP


def _write_mtx(path, A):
    scipy.io.mmwrite(str(path), sp.csr_matrix(np.asarray(A)))
    return str(path)


def particle_scene(tmp_path, signs, mu, analyses=("mceip_lambda2", "mceip_mu", "enumerate", "sufficient", "necessary"),
                   fmt="mtx"):
    from app.systems.particles.path import particle_matrices
    Kd, Md = particle_matrices(KP, MP, PHI)
    if fmt == "mtx":
        k, m = _write_mtx(tmp_path / "K.mtx", Kd), _write_mtx(tmp_path / "M.mtx", Md)
    else:                                   # PETSc binary
        from petsc4py import PETSc
        names = []
        for name, A in (("K.petsc", Kd), ("M.petsc", Md)):
            mat = PETSc.Mat().createAIJ(A.shape, comm=PETSc.COMM_SELF)
            mat.setUp()
            mat.setValues(range(4), range(4), A)
            mat.assemble()
            v = PETSc.Viewer().createBinary(str(tmp_path / name), mode="w", comm=PETSc.COMM_SELF)
            mat.view(v)
            v.destroy()
            mat.destroy()
            names.append(str(tmp_path / name))
        k, m = names
    S1, S2 = signs
    return {"name": "tpm", "system": {"type": "matrices", "K": k, "M": m, "contact": [[0, 1, 1], [2, 3, 1]],
                                      "state": {"reactions": [[S1 * mu, -1.0], [S2 * mu, -1.0]]}},
            "mu": mu, "analyses": list(analyses)}


@pytest.mark.parametrize("signs,mu,count", CASES)
def test_table1_lambda2_through_files(tmp_path, signs, mu, count):
    expected = analytic_lambda2(KP, MP, PHI, mu, *signs)
    assert len(expected) == count
    a = run_scene(particle_scene(tmp_path, signs, mu))["states"][0]["analyses"]
    assert_same_set(a["mceip_lambda2"]["solutions"], expected)
    assert_same_set(a["enumerate"]["problems"]["lambda2"]["solutions"], expected)


@pytest.mark.parametrize("fmt", ["mtx", "petsc"])
@pytest.mark.parametrize("signs,count", [((1, 1), 1), ((-1, -1), 1), ((-1, 1), 0), ((1, -1), 3)])
def test_table1_mu_through_files(tmp_path, signs, count, fmt):
    expected = analytic_mu(PHI, *signs)
    assert len(expected) == count
    res = run_scene(particle_scene(tmp_path, signs, 1.0, fmt=fmt))
    a = res["states"][0]["analyses"]
    assert_same_set(a["mceip_mu"]["solutions"], expected)
    assert_same_set(a["enumerate"]["problems"]["mu"]["solutions"], expected)
    # and the same numbers as the built-in two-particle scene
    ref = run_scene({"name": "tp", "system": {"type": "two_particles", "k": KP, "m": MP, "phi_deg": PHI,
                                              "signs": list(signs)}, "mu": 1.0,
                     "analyses": ["mceip_lambda2", "mceip_mu", "enumerate", "sufficient", "necessary"]})
    b = ref["states"][0]["analyses"]
    assert a["necessary"]["min_eig_K_sym"] == pytest.approx(b["necessary"]["min_eig_K_sym"], rel=1e-12)
    assert a["sufficient"]["lambda2"] == pytest.approx(b["sufficient"]["lambda2"], rel=1e-12)


def test_random_system_through_files_equals_in_memory(tmp_path):
    """K, M, contact DOFs (random order, random signs) and a classified state, written to files
    and read back, give the same analyses as the system built in memory."""
    from app.analyses.pencils.reduced import dense
    from app.analyses.runner import analyse_state
    from app.common.stages import Stages
    from app.loading.classify import classify
    from app.scene.schema import parse_scene
    from app.systems.discrete import random_contact_problem
    mu = 0.8
    analyses = ["necessary", "sufficient", "mceip_mu", "mceip_lambda2", "enumerate"]
    for seed in range(4):
        rng = np.random.default_rng(100 + seed)
        system, state = random_contact_problem(rng, n_contact=5, n_interior=6, n_slip=3, n_stick=1, mu=mu,
                                               comm=MPI.COMM_WORLD, stages=Stages())
        Kd, Md = dense(system.K), dense(system.mass())
        contact = [[nd.dof_T, nd.dof_N, nd.sign_T, nd.sign_N] for nd in system.nodes]
        data = {"name": "rnd", "mu": mu, "analyses": analyses, "mceip_lambda2_mu": mu,
                "system": {"type": "matrices", "K": "K.mtx", "M": "M.npy", "contact": contact,
                           "gaps": [float(-u) for u in state.u_N],
                           "state": {"reactions": [[float(t), float(n)] for t, n in zip(state.r_T, state.r_N)]}}}
        _write_mtx(tmp_path / "K.mtx", Kd)
        np.save(tmp_path / "M.npy", Md)
        scene = parse_scene(data, "rnd.yaml", tmp_path)        # paths relative to the scene's folder
        mem = analyse_state(system, classify(state, mu), scene)
        system.destroy()
        files = run_scene_in(scene)["states"][0]["analyses"]
        for key in ("mceip_mu", "mceip_lambda2"):
            assert _values(files[key]) == pytest.approx(_typed_values(mem[key]), rel=1e-9, abs=1e-12)
            assert _patterns(files[key]) == _typed_patterns(mem[key])
        for p in ("mu", "lambda2"):
            assert _values(files["enumerate"]["problems"][p]) == pytest.approx(
                _typed_values(mem["enumerate"].problems[p]), rel=1e-9, abs=1e-12)
        assert files["necessary"]["min_eig_K_sym"] == pytest.approx(mem["necessary"].min_eig_K_sym, rel=1e-10)
        assert files["sufficient"]["lambda2"] == pytest.approx(mem["sufficient"].lambda2, rel=1e-10)


def run_scene_in(scene):
    from app.study.run import study
    return study(scene, MPI.COMM_WORLD).to_dict()


def _values(a):
    return sorted(s["value"] for s in a["solutions"])


def _patterns(a):
    return sorted((round(s["value"], 8), tuple(s["pattern"])) for s in a["solutions"])


def _typed_values(a):
    """:func:`_values` of a typed outcome (app/analyses/outcomes.py)."""
    return sorted(s.value for s in a.solutions)


def _typed_patterns(a):
    """:func:`_patterns` of a typed outcome."""
    return sorted((round(s.value, 8), tuple(s.pattern)) for s in a.solutions)


BLOCK = {"type": "block", "nx": 10, "ny": 5}


@pytest.fixture(scope="module")
def block_as_matrices(tmp_path_factory):
    """The 10 x 5 block (built-in path) and the same block exported as a matrices scene whose force
    phases are the reduced loads of CD's prescribed motion (K u = gx f_x + gy f_y + B^T r)."""
    from app.analyses.pencils.reduced import dense, gather_vec
    from app.common.stages import Stages
    from app.scene.schema import parse_scene
    from app.systems.block.path import build_block_system
    d = tmp_path_factory.mktemp("blockm")
    base = {"name": "b", "system": BLOCK, "mu": 1.1, "analyses": ["mceip_mu"]}
    ref = run_scene(base)
    cfg = parse_scene(base).system
    system, ops, flex = build_block_system(cfg, MPI.COMM_WORLD, Stages())
    _write_mtx(d / "K.mtx", dense(system.K))
    fx, fy = gather_vec(ops.load_x), gather_vec(ops.load_y)
    contact = [[nd.dof_T, nd.dof_N, nd.sign_T, nd.sign_N] for nd in system.nodes]
    xs = [nd.x for nd in system.nodes]
    system.destroy()
    ops.destroy()
    depth = ref["path"]["normal_displacement"]
    ntan = len(ref["states"]) - ref["path"]["normal_steps"]
    step = ref["path"]["tangential_step"]
    np.save(d / "fy.npy", -depth * fy)
    data = {"name": "bm", "mu": 1.1, "analyses": ["mceip_mu"],
            "system": {"type": "matrices", "K": "K.mtx", "contact": contact, "positions": xs,
                       "forces": [{"force": "fy.npy", "steps": 10},
                                  {"force": list(-step * ntan * fx), "steps": ntan}]}}
    return ref, run_scene_in(parse_scene(data, "bm.yaml", d))


def test_block_as_matrices_and_forces_equals_built_in_block(block_as_matrices):
    ref, got = block_as_matrices
    assert len(got["states"]) == len(ref["states"])
    for a, b in zip(ref["states"], got["states"]):
        assert [n["status"] for n in a["nodes"]] == [n["status"] for n in b["nodes"]]
        assert [n["sign"] for n in a["nodes"]] == [n["sign"] for n in b["nodes"]]
        rs = max(abs(n["r_N"]) for n in a["nodes"])
        for na, nb in zip(a["nodes"], b["nodes"]):
            assert nb["r_N"] == pytest.approx(na["r_N"], abs=1e-8 * rs)
            assert nb["r_T"] == pytest.approx(na["r_T"], abs=1e-8 * rs)
        assert _values(b["analyses"]["mceip_mu"]) == pytest.approx(_values(a["analyses"]["mceip_mu"]), rel=1e-8)
    assert got["states"][9]["load"]["normal_resultant"] == pytest.approx(55.0, rel=1e-10)
    assert got["distinct_classifications"] == ref["distinct_classifications"]


def test_force_path_with_gaps_is_an_equilibrium(tmp_path):
    """A random system pushed by force phases onto the obstacle with initial gaps: every state
    satisfies K u = f + B^T r, Signorini with the gaps, and Coulomb (independent dense check)."""
    rng = np.random.default_rng(7)
    n_c, n_i = 4, 5
    n = 2 * n_c + n_i
    A = rng.standard_normal((n, n))
    Kd = A @ A.T + 0.5 * n * np.eye(n)
    contact = [[2 * i, 2 * i + 1, 1, 1] for i in range(n_c)]
    gaps = [0.0, 0.01, 0.0, 0.3]
    f1 = np.zeros(n)
    f1[1::2][:n_c] = 5.0                    # push every node towards the obstacle (outward normal +N)
    f2 = rng.standard_normal(n)
    _write_mtx(tmp_path / "K.mtx", Kd)
    mu = 0.4
    res = run_scene({"name": "g", "mu": mu, "analyses": ["mceip_mu"],
                     "system": {"type": "matrices", "K": str(tmp_path / "K.mtx"), "contact": contact, "gaps": gaps,
                                "forces": [{"force": list(f1), "steps": 3}, {"force": list(f2), "steps": 4}]}})
    assert len(res["states"]) == 7
    statuses = set()
    for k, st in enumerate(res["states"]):
        f = f1 * min(k + 1, 3) / 3 + (f2 * (k - 2) / 4 if k >= 3 else 0)
        rT = np.array([x["r_T"] for x in st["nodes"]])
        rN = np.array([x["r_N"] for x in st["nodes"]])
        uN = np.array([x["u_N"] for x in st["nodes"]])
        rhs = f.copy()
        rhs[0:2 * n_c:2] += rT
        rhs[1:2 * n_c:2] += rN
        u = np.linalg.solve(Kd, rhs)
        scale = np.abs(np.concatenate([rT, rN])).max()
        assert u[1:2 * n_c:2] - np.array(gaps) == pytest.approx(uN, abs=1e-9 * np.abs(u).max())
        assert np.all(uN <= 1e-12) and np.all(rN <= 1e-12 * scale)
        assert np.abs(uN * rN).max() <= 1e-9 * scale * np.abs(u).max()
        assert np.all(np.abs(rT) <= mu * -rN + 1e-9 * scale)
        statuses |= {x["status"] for x in st["nodes"]}
    assert {"free", "slip"} <= statuses      # the data exercise lift-off/gaps and sliding


@pytest.mark.parametrize("change,needle", [
    (lambda s, d: s["system"].update(K="nope.mtx"), "system.K = 'nope.mtx': no such file"),
    (lambda s, d: s["system"].update(K="bad.mtx"), "system.K = 'bad.mtx': cannot read bad.mtx as a Matrix Market"),
    (lambda s, d: s["system"].update(K="rect.mtx"), "shape 4 x 3: a square"),
    (lambda s, d: s["system"].update(K="nonsym.mtx"), "system.K = 'nonsym.mtx': not symmetric"),
    (lambda s, d: s["system"].update(K="indef.mtx"), "not positive definite"),
    (lambda s, d: s["system"].update(M="M3.mtx"), "system.M = 'M3.mtx': shape 3 x 3 differs from K's 4 x 4"),
    (lambda s, d: s["system"].update(contact=[[0, 1, 1], [2, 9, 1]]), "system.contact.1 = [2, 9, 1, 1]: DOF index out of range"),
    (lambda s, d: s["system"].update(contact=[[0, 1, 1], [1, 3, 1]]), "system.contact.1 = [1, 3, 1, 1]: DOF 1 is already used"),
    (lambda s, d: s["system"].update(contact=[[0, 1, 2]]), "system.contact.0 = [0, 1, 2]: allowed: [T, N, sign_N]"),
    (lambda s, d: s["system"].update(contact=[[0, 1.5, 1]]), "system.contact.0"),
    (lambda s, d: s["system"].pop("M"), "system.M = None: the analyses necessary, mceip_lambda2 need a mass matrix"),
    (lambda s, d: s["system"]["state"].update(reactions=[[1, -1]]), "1 pairs for 2 contact nodes"),
    (lambda s, d: s["system"]["state"].update(reactions=[[1, -1], [0, 1]]), "system.state.reactions.1 = [0.0, 1.0]: r_N > 0"),
    (lambda s, d: s["system"]["state"].update(reactions=[[1, -1], [5, -1]]), "outside the Coulomb cone"),
    (lambda s, d: s["system"].update(forces=[{"force": [1, 2], "steps": 2}]), "give exactly one of 'state'"),
    (lambda s, d: (s["system"].pop("state"), s["system"].update(forces=[{"force": [1, 2]}])),
     "system.forces.0.force = '<2 values>': 2 values: K has 4 rows"),
    (lambda s, d: (s["system"].pop("state"), s["system"].update(forces=[{"force": "f.mtx"}])),
     "system.forces.0.force = 'f.mtx': no such file"),
    (lambda s, d: s.update(loading={"normal_force": 3}), "loading = "),
    (lambda s, d: s["system"].update(type="matrix"), "allowed types are 'two_particles', 'block', 'matrices'"),
])
def test_user_mistakes_are_one_line_errors(tmp_path, scene_file, change, needle):
    import yaml
    (tmp_path / "K.mtx").write_text("%%MatrixMarket matrix coordinate real general\n4 4 4\n1 1 2\n2 2 2\n3 3 2\n4 4 2\n")
    (tmp_path / "M.mtx").write_text("%%MatrixMarket matrix coordinate real general\n4 4 4\n1 1 1\n2 2 1\n3 3 1\n4 4 1\n")
    (tmp_path / "M3.mtx").write_text("%%MatrixMarket matrix coordinate real general\n3 3 3\n1 1 1\n2 2 1\n3 3 1\n")
    (tmp_path / "bad.mtx").write_text("hello\n")
    (tmp_path / "rect.mtx").write_text("%%MatrixMarket matrix coordinate real general\n4 3 1\n1 1 1\n")
    (tmp_path / "nonsym.mtx").write_text("%%MatrixMarket matrix coordinate real general\n4 4 5\n1 1 2\n2 2 2\n3 3 2\n"
                                         "4 4 2\n1 2 1\n")
    (tmp_path / "indef.mtx").write_text("%%MatrixMarket matrix coordinate real general\n4 4 6\n1 1 1\n2 2 1\n3 3 1\n"
                                        "4 4 1\n1 2 3\n2 1 3\n")
    s = {"name": "e", "mu": 1.0, "analyses": ["necessary", "mceip_lambda2", "mceip_mu"],
         "system": {"type": "matrices", "K": "K.mtx", "M": "M.mtx", "contact": [[0, 1, 1], [2, 3, -1]],
                    "state": {"reactions": [[1, -1], [0, -2]]}}}
    change(s, tmp_path)
    path = scene_file(yaml.safe_dump(s), "scene.yaml")
    p = run_cli_here("validate", str(path), cwd="/")     # paths are relative to the scene file, not cwd
    assert p.returncode == 2, (p.stdout, p.stderr)
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error:"), p.stderr
    assert needle in lines[0], lines[0]


@pytest.mark.slow
def test_cli_run_relative_paths_and_mpi(tmp_path):
    """A matrices scene with relative paths runs from any folder, and gives the same numbers on 2 ranks."""
    import yaml
    s = particle_scene(tmp_path, (1, -1), 7.0)
    s["system"]["K"], s["system"]["M"] = "K.mtx", "M.mtx"
    (tmp_path / "s.yaml").write_text(yaml.safe_dump(s))
    out = results_on_ranks(tmp_path / "s.yaml", tmp_path, cwd="/")
    a, b = (out[r]["states"][0]["analyses"] for r in (1, 2))
    for key in ("mceip_mu", "mceip_lambda2"):
        assert _values(a[key]) == pytest.approx(_values(b[key]), rel=1e-10)
        assert len(a[key]["solutions"]) >= 2
    assert out[2]["mpi_ranks"] == 2
