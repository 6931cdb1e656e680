"""``system.type: gmsh`` with a loading program and a straight obstacle (app/systems/gmsh_*.py,
app/loading/program.py).

- The paper's block as a Gmsh file plus the program "press CD to 55 N, then drag it left" equals
  the built-in block: identical classifications at every state and MCEIP-mu to 1e-8, on the
  paper's mesh (crossed 20 x 10, as .msh) and on the shipped .geo (one diagonal per cell, the
  built-in pattern "right").
- Inclined obstacles: the same block, mesh, obstacle and motions rotated by any angle give the
  same states and mu (per-node frames); an initial gap is closed by a rigid motion first.
- One-line errors for a missing file, a missing or empty physical group, 3D, mixed and inverted
  meshes, and a body the program leaves floating.
"""
import math
import pathlib

import numpy as np
import pytest
from conftest import ROOT, results_on_ranks, run_cli, run_cli_here, run_scene

GEO = ROOT / "app" / "scenes" / "gmsh" / "block.geo"


def write_block_msh(path: pathlib.Path, nx: int, ny: int, pattern: str, angle_deg: float = 0.0,
                    shift=(0.0, 0.0)) -> str:
    """The built-in block mesh (app/systems/block/mesh.py) as a .msh, rotated about A and shifted."""
    import gmsh

    from app.systems.block.mesh import _add_structured_model
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    try:
        gmsh.model.add("b")
        _add_structured_model(gmsh, 80.0, 40.0, nx, ny, pattern)
        c, s = math.cos(math.radians(angle_deg)), math.sin(math.radians(angle_deg))
        tags, x, _ = gmsh.model.mesh.getNodes()
        for t, p in zip(tags, x.reshape(-1, 3)):
            gmsh.model.mesh.setNode(int(t), [c * p[0] - s * p[1] + shift[0], s * p[0] + c * p[1] + shift[1], 0.0], [])
        gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
        gmsh.write(str(path))
    finally:
        gmsh.finalize()
    return str(path)


def gmsh_scene(file, mu=1.1, angle_deg=0.0, point=(0.0, 0.0), analyses=("mceip_mu",), press=(0.0, -1.0), **extra):
    c, s = math.cos(math.radians(angle_deg)), math.sin(math.radians(angle_deg))
    rot = lambda v: [c * v[0] - s * v[1], s * v[0] + c * v[1]]   # noqa: E731
    system = {"type": "gmsh", "file": str(file), "contact": "AB", "prescribed": {"CD": "xy"},
              "material": {"E": 5.0, "nu": 0.48, "density": 1.2e-9}, "thickness": 9.6,
              "obstacle": {"point": list(point), "normal": rot([0.0, -1.0])},
              "program": [{"name": "press", "steps": 10, "displacement": {"CD": {"translation": rot(press)}},
                           "until": {"normal_force": 55.0}},
                          {"name": "drag", "steps": 500, "displacement": {"CD": {"translation": rot([-10.0, 0.0])}}}]}
    system.update(extra)
    return {"name": "g", "system": system, "mu": mu, "analyses": list(analyses)}


def block_scene(nx, ny, pattern, analyses=("mceip_mu",)):
    return {"name": "b", "system": {"type": "block", "nx": nx, "ny": ny, "pattern": pattern}, "mu": 1.1,
            "analyses": list(analyses)}


def _mu_values(state, below=np.inf):
    return sorted(s["value"] for s in state["analyses"]["mceip_mu"]["solutions"] if s["value"] <= below)


def assert_same_path(ref, got, first=0, rtol=1e-8, reactions=1e-8, below=np.inf):
    """Identical classifications and slip signs, reactions to ``reactions`` of the state's scale,
    MCEIP-mu to rtol (the values up to ``below``: the others found, unproven and ill-conditioned)."""
    a_states, b_states = ref["states"][first:], got["states"][first:]
    assert len(a_states) == len(b_states)
    for a, b in zip(a_states, b_states):
        assert [n["status"] for n in a["nodes"]] == [n["status"] for n in b["nodes"]], a["index"]
        assert [n["sign"] for n in a["nodes"]] == [n["sign"] for n in b["nodes"]], a["index"]
        scale = max(abs(n["r_N"]) for n in a["nodes"])
        for na, nb in zip(a["nodes"], b["nodes"]):
            assert nb["r_N"] == pytest.approx(na["r_N"], abs=reactions * scale)
            assert nb["r_T"] == pytest.approx(na["r_T"], abs=reactions * scale)
        assert _mu_values(b, below) == pytest.approx(_mu_values(a, below), rel=rtol)


@pytest.fixture(scope="module")
def paper_block():
    return run_scene(block_scene(20, 10, "crossed"))


def test_paper_mesh_program_equals_built_in_block(tmp_path, paper_block):
    got = run_scene(gmsh_scene(write_block_msh(tmp_path / "paper.msh", 20, 10, "crossed")))
    assert_same_path(paper_block, got)
    assert got["distinct_classifications"] == paper_block["distinct_classifications"]
    assert got["path"]["phases"][0]["homogeneous"] is True
    assert got["states"][9]["load"]["normal_resultant"] == pytest.approx(55.0, rel=1e-10)
    assert _mu_values(got["states"][-1]) == pytest.approx([1.7048], abs=5e-5)
    assert "gross sliding" in got["path"]["end"]


def test_shipped_geo_equals_built_in_right_pattern():
    ref = run_scene(block_scene(20, 10, "right"))
    got = run_scene(gmsh_scene(GEO))
    assert_same_path(ref, got)


@pytest.mark.parametrize("angle", [30.0, -17.0, 90.0])
def test_inclined_obstacle_is_the_rotated_problem(tmp_path, angle):
    """Rotating the body, the obstacle line (through a shifted point) and the motions is a change of
    frame: classifications and mu are unchanged (per-node T/N frames in the stability code)."""
    ref = run_scene(block_scene(10, 5, "crossed"))
    shift = (3.0, -2.0)
    f = write_block_msh(tmp_path / "rot.msh", 10, 5, "crossed", angle, shift)
    got = run_scene(gmsh_scene(f, angle_deg=angle, point=shift))
    assert_same_path(ref, got)


@pytest.mark.parametrize("gap", [0.3, 3.0])
def test_initial_gap_closed_by_a_rigid_motion(tmp_path, gap):
    """The block lifted above the obstacle (less and more than the bonded estimate of the press,
    0.5 mm): nodes are free with u_N = -(gap - CD's motion) until the gap closes; the
    force-controlled press then reaches 55 N (bracketing and regula falsi, not homogeneous)."""
    f = write_block_msh(tmp_path / "lifted.msh", 10, 5, "crossed", 0.0, (0.0, gap))
    res = run_scene(gmsh_scene(f))
    info = res["path"]
    assert info["initial_gaps"] == pytest.approx([gap] * 11, abs=1e-12)
    assert info["phases"][0]["homogeneous"] is False
    depth = -res["states"][0]["load"]["parameters"]["motion.CD.ty"]     # CD's motion after step 1
    press = res["states"][:10]
    assert press[-1]["load"]["normal_resultant"] == pytest.approx(55.0, rel=1e-10)
    for st in press:
        d = -st["load"]["parameters"]["motion.CD.ty"]
        if d < gap:
            assert all(n["status"] == "free" and n["r_N"] == 0.0 for n in st["nodes"])
            assert [n["u_N"] for n in st["nodes"]] == pytest.approx([-(gap - d)] * 11, abs=1e-9 * gap)
    assert depth > 0 and any(-st["load"]["parameters"]["motion.CD.ty"] < gap for st in press)


def test_gmsh_scene_same_numbers_on_two_ranks(tmp_path):
    import yaml
    f = write_block_msh(tmp_path / "b.msh", 10, 5, "crossed", 25.0)
    s = gmsh_scene("b.msh", angle_deg=25.0, analyses=["necessary", "mceip_mu"])
    (tmp_path / "s.yaml").write_text(yaml.safe_dump(s))
    out = results_on_ranks(tmp_path / "s.yaml", tmp_path)
    assert f
    a, b = out[1], out[2]
    assert_same_path(a, b)
    for x, y in zip(a["states"], b["states"]):
        assert y["analyses"]["necessary"]["min_eig_K_sym"] == pytest.approx(
            x["analyses"]["necessary"]["min_eig_K_sym"], rel=1e-8)


GOOD = """
Point(1) = {0, 0, 0, 5}; Point(2) = {40, 0, 0, 5}; Point(3) = {40, 20, 0, 5}; Point(4) = {0, 20, 0, 5};
Line(1) = {1, 2}; Line(2) = {2, 3}; Line(3) = {3, 4}; Line(4) = {4, 1};
Curve Loop(1) = {1, 2, 3, 4}; Plane Surface(1) = {1};
Physical Curve("bottom") = {1}; Physical Curve("top") = {3}; Physical Surface("body") = {1};
"""


def _err_scene(file, **system):
    s = {"name": "e", "mu": 0.5, "analyses": ["mceip_mu"],
         "system": {"type": "gmsh", "file": file, "contact": "bottom", "prescribed": {"top": "xy"},
                    "material": {"E": 1.0, "nu": 0.3},
                    "program": [{"steps": 2, "displacement": {"top": {"translation": [0, -0.1]}}}]}}
    s["system"].update(system)
    return s


@pytest.mark.parametrize("geo,system,needle", [
    (None, {"file": "nope.geo"}, "system.file = 'nope.geo': no such file"),
    (GOOD, {"contact": "bottm"}, "system.contact = 'bottm': no physical curve 'bottm' in m.geo; physical curves: bottom, top"),
    (GOOD.replace('Physical Curve("top") = {3};', 'Physical Curve("top") = {3}; Physical Curve("empty") = {};'),
     {"contact": "empty"}, "physical curve 'empty'"),
    (GOOD + "Extrude {0, 0, 5} { Surface{1}; }\nPhysical Volume(9) = {1};\n", {}, "a 3D model"),
    (GOOD + "Recombine Surface {1};\n", {}, "element types"),
    (GOOD.replace('Physical Surface("body") = {1};', ""), {}, "no physical surface"),
    (GOOD, {"materials": {"body": {"E": 1, "nu": 0.3}}}, "give either 'material'"),
    (GOOD, {"material": None, "materials": {"bod": {"E": 1, "nu": 0.3}}}, "no physical surface 'bod'"),
    (GOOD, {"prescribed": {}}, "'top' is not a prescribed curve"),
    (GOOD, {"prescribed": {"top": "x"}}, "only the x component of 'top' is prescribed"),
    (GOOD, {"contact": "top", "prescribed": {"top": "xy"}}, "the contact curve cannot also be prescribed"),
    (GOOD, {"program": [{"steps": 2, "force": {"top": [0, -1]}}], "prescribed": {}},
     "the stiffness is singular"),
    (GOOD, {"obstacle": {"point": [0, 1], "normal": [0, -1]}}, "inside the obstacle"),
    # the normal points into the body (the contact curve is on the line, the rest of the body beyond it)
    (GOOD, {"obstacle": {"point": [0, 0], "normal": [0, 1]}}, "the body starts on the obstacle's side of the line"),
    (GOOD, {"obstacle": {"point": [5, -3], "angle_deg": 180}}, "the body starts on the obstacle's side of the line"),
])
def test_user_mistakes_are_one_line_errors(tmp_path, geo, system, needle):
    import yaml
    if geo is not None:
        (tmp_path / "m.geo").write_text(geo)
    s = _err_scene(system.pop("file", "m.geo"), **system)
    if s["system"].get("material") is None:
        s["system"].pop("material", None)
    (tmp_path / "s.yaml").write_text(yaml.safe_dump(s))
    p = run_cli_here("run", str(tmp_path / "s.yaml"), "-o", str(tmp_path / "out"), "-q", cwd="/")
    assert p.returncode == 2, (p.stdout, p.stderr)
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error:"), p.stderr
    assert needle in lines[0], lines[0]
    assert not (tmp_path / "out").exists()


INVERTED_MSH = """$MeshFormat
2.2 0 8
$EndMeshFormat
$PhysicalNames
3
1 1 "AB"
1 2 "CD"
2 3 "block"
$EndPhysicalNames
$Nodes
6
1 0 0 0
2 4 0 0
3 8 0 0
4 0 4 0
5 4 4 0
6 8 4 0
$EndNodes
$Elements
8
1 1 2 1 1 1 2
2 1 2 1 1 2 3
3 1 2 2 2 4 5
4 1 2 2 2 5 6
5 2 2 3 1 1 5 2
6 2 2 3 1 1 5 4
7 2 2 3 1 2 3 6
8 2 2 3 1 2 6 5
$EndElements
"""


def test_inverted_elements_are_an_error(tmp_path):
    """Element 5 is clockwise, the other three counter-clockwise."""
    import yaml
    (tmp_path / "inv.msh").write_text(INVERTED_MSH)
    s = _err_scene("inv.msh", contact="AB", prescribed={"CD": "xy"},
                   program=[{"steps": 1, "displacement": {"CD": {"translation": [0, -0.1]}}}])
    (tmp_path / "s.yaml").write_text(yaml.safe_dump(s))
    p = run_cli_here("validate", str(tmp_path / "s.yaml"))
    assert p.returncode == 2 and "inverted elements: 1 of 4 triangles" in p.stderr, p.stderr
    (tmp_path / "inv.msh").write_text(INVERTED_MSH.replace("5 2 2 3 1 1 5 2", "5 2 2 3 1 1 2 5"))
    p = run_cli_here("validate", str(tmp_path / "s.yaml"))
    assert p.returncode == 0, p.stderr


def test_force_and_traction_loads(tmp_path):
    """Pressed by CD's motion, then pushed sideways by a load on the lateral sides (80 mm of curve):
    a total force F and the traction F / (80 mm x thickness) give the same states; the push changes
    the tangential reactions; pure force control in the normal direction leaves the body floating
    (a one-line error naming the remedy)."""
    f = write_block_msh(tmp_path / "b.msh", 10, 5, "crossed")
    base = gmsh_scene(f, mu=0.6)
    press = base["system"]["program"][0]
    base["system"]["program"] = [press, {"steps": 5, "force": {"lateral": [-20.0, 0.0]}}]
    res_f = run_scene(base)
    base["system"]["program"] = [press, {"steps": 5, "traction": {"lateral": [-20.0 / (80.0 * 9.6), 0.0]}}]
    res_t = run_scene(base)
    assert len(res_f["states"]) == 15
    assert_same_path(res_f, res_t)
    t = [s["load"]["tangential_resultant"] for s in res_f["states"][9:]]
    assert all(abs(b - a) > 1e-3 for a, b in zip(t, t[1:]))
    base["system"]["prescribed"] = {"lateral": "x"}
    base["system"]["program"] = [{"steps": 4, "force": {"CD": [0.0, -55.0]}}]
    import yaml
    (tmp_path / "s.yaml").write_text(yaml.safe_dump(base))
    p = run_cli("run", str(tmp_path / "s.yaml"), "-o", str(tmp_path / "o"), "-q")
    assert p.returncode == 2 and "the stiffness is singular" in p.stderr and len(p.stderr.splitlines()) == 1, p.stderr


def test_rotation_about_a_point_mirrors(tmp_path):
    """CD pressed, then rotated by +theta or -theta about its centre (40, 40): the crossed mesh is
    mirror-symmetric about x = 40, so the normal reactions are mirror images, and the tilt loads
    one side (the side CD's rotation moves down)."""
    f = write_block_msh(tmp_path / "b.msh", 10, 5, "crossed")
    out = {}
    for th in (2.0, -2.0):
        s = gmsh_scene(f, mu=0.0)
        s["system"]["program"] = [s["system"]["program"][0],
                                  {"steps": 3, "stop_at_gross_sliding": False,
                                   "displacement": {"CD": {"rotation_deg": th, "about": [40.0, 40.0]}}}]
        s["system"]["program"][0]["stop_at_gross_sliding"] = False
        s["analyses"] = []
        out[th] = run_scene(s)["states"][-1]["nodes"]
    a = np.array([n["r_N"] for n in out[2.0]])
    b = np.array([n["r_N"] for n in out[-2.0]])
    assert a == pytest.approx(b[::-1], abs=1e-8 * np.abs(a).max())
    assert a[0] < a[-1] and -a[:5].sum() > -a[-5:].sum()    # +theta (counter-clockwise) presses A's side (r_N < 0)


def test_p2_plane_strain_equals_built_in_block(tmp_path):
    """P2 and plane strain through the .geo (10 x 5 cells) equal the built-in block with the same options."""
    (tmp_path / "b.geo").write_text(GEO.read_text().replace("nx = 20; ny = 10;", "nx = 10; ny = 5;"))
    ref = run_scene({"name": "b", "system": {"type": "block", "nx": 10, "ny": 5, "pattern": "right", "degree": 2,
                                             "plane": "strain"}, "mu": 1.1, "analyses": ["mceip_mu"]})
    got = run_scene(gmsh_scene(tmp_path / "b.geo", degree=2, plane="strain"))
    assert_same_path(ref, got)


def test_unnamed_physical_groups_are_named_by_their_tags(tmp_path):
    geo = GOOD.replace('Physical Curve("bottom") = {1}; Physical Curve("top") = {3}; Physical Surface("body") = {1};',
                       "Physical Curve(11) = {1}; Physical Curve(12) = {3}; Physical Surface(5) = {1};")
    (tmp_path / "t.geo").write_text(geo)
    res = run_scene({"name": "t", "mu": 0.5, "analyses": [],
                     "system": {"type": "gmsh", "file": str(tmp_path / "t.geo"), "contact": 11, "prescribed": {12: "xy"},
                                "materials": {5: {"E": 1.0, "nu": 0.3}},
                                "program": [{"steps": 2, "displacement": {12: {"translation": [0, -0.1]}}}]}})
    assert len(res["states"]) == 2 and res["states"][-1]["load"]["normal_resultant"] > 0


def test_until_scales_the_motion_not_the_loads_of_its_phase(tmp_path):
    """``until: normal_force`` scales the phase's prescribed motion only: a force applied in the same
    phase is applied as given (it used to be multiplied by the same factor)."""
    (tmp_path / "m.geo").write_text(GOOD + 'Physical Curve("sides") = {2, 4};\n')
    s = _err_scene("m.geo")
    s["system"]["program"] = [{"steps": 2, "displacement": {"top": {"translation": [0, -1]}}, "force": {"sides": [0.05, 0]},
                               "until": {"normal_force": 2.0}}]
    s["analyses"] = []
    s["system"]["file"] = str(tmp_path / "m.geo")
    res = run_scene(s)
    end = res["states"][-1]["load"]
    assert end["normal_resultant"] == pytest.approx(2.0, rel=1e-10)
    assert end["parameters"]["force.sides.x"] == pytest.approx(0.05, rel=1e-14)
    assert res["path"]["phases"][0]["homogeneous"] is False
    assert abs(end["parameters"]["motion.top.ty"]) != pytest.approx(1.0, rel=1e-6)     # the motion was scaled


@pytest.mark.parametrize("degree", [1, 2])
def test_lumped_mass_is_positive_and_keeps_the_mass(tmp_path, degree):
    """mass: lumped gives a positive diagonal M carrying the body's mass rho t A per direction; for
    P2 the row sums vanish at the vertices (a singular M before), so the HRZ lumping is used."""
    from mpi4py import MPI

    from app.analyses.pencils.reduced import dense
    from app.common.stages import Stages
    from app.scene.schema import parse_scene
    from app.systems.gmsh import path as gmsh_body
    (tmp_path / "m.geo").write_text(GOOD)
    s = _err_scene(str(tmp_path / "m.geo"), prescribed={}, foundation=1e-6, degree=degree, mass="lumped",
                   material={"E": 1.0, "nu": 0.3, "density": 2.5},
                   program=[{"steps": 1, "gravity": [0, -1]}])
    system = gmsh_body.build(parse_scene(s).system, MPI.COMM_WORLD, Stages())
    try:
        M = dense(system.mass())
    finally:
        system.destroy()
    d = np.diag(M)
    assert np.all(d > 1e-3 * d.max()) and np.abs(M - np.diag(d)).max() == 0.0
    assert d.sum() / 2 == pytest.approx(2.5 * 1.0 * 40 * 20, rel=1e-12)


def test_named_physical_groups_may_be_given_by_their_tags(tmp_path):
    """``Physical Curve("bottom") = {1}`` has the tag 1: ``contact: 1`` names it as ``contact: bottom``
    (it was an error: "no physical curve '1'"), for curves, prescribed curves, materials and phases."""
    from app.systems.gmsh.mesh import model_info
    (tmp_path / "m.geo").write_text(GOOD)
    info = model_info(tmp_path / "m.geo", "m.geo")
    bottom, top, body = info.curves["bottom"][0], info.curves["top"][0], info.surfaces["body"][0]
    named = _err_scene(str(tmp_path / "m.geo"), material=None, materials={"body": {"E": 1.0, "nu": 0.3}})
    named["system"].pop("material")
    tagged = _err_scene(str(tmp_path / "m.geo"), contact=bottom, prescribed={top: "xy"}, material=None,
                        materials={body: {"E": 1.0, "nu": 0.3}},
                        program=[{"steps": 2, "displacement": {top: {"translation": [0, -0.1]}}}])
    tagged["system"].pop("material")
    a, b = run_scene(named), run_scene(tagged)
    assert [s["load"]["normal_resultant"] for s in a["states"]] == [s["load"]["normal_resultant"] for s in b["states"]]
    assert a["states"][-1]["load"]["normal_resultant"] > 0


def test_contact_nodes_with_one_prescribed_component_are_reported(tmp_path):
    """A symmetry line held in x through the contact curve: its node on the contact curve is left
    out of the contact set (not modelled: a normal-only contact node); the results say so."""
    (tmp_path / "m.geo").write_text(GOOD + 'Physical Curve("sym") = {4};\n')
    s = _err_scene(str(tmp_path / "m.geo"), prescribed={"sym": "x"}, foundation=1e-6,
                   program=[{"steps": 2, "force": {"top": [0, -0.1]}}])
    s["analyses"] = []
    res = run_scene(s)
    assert all(n["x"] > 0 for n in res["states"][0]["nodes"])
    w = [x for x in res["warnings"] if "left out of the contact set" in x]
    assert len(w) == 1 and w[0].startswith("1 node(s) of the contact curve 'bottom'") and "(0, 0)" in w[0], res["warnings"]


def test_part_of_the_body_beyond_the_obstacle_line_is_a_warning(tmp_path):
    """A body on a ledge: the obstacle is an infinite line, a part hanging beside the ledge starts
    beyond it. Only the contact curve is kept out of the obstacle: a warning, not an error (an
    error when most of the body is beyond: the normal points into the body, see the mistakes)."""
    (tmp_path / "m.geo").write_text("""
Point(1) = {0, 0, 0, 2}; Point(2) = {20, 0, 0, 2}; Point(3) = {20, -3, 0, 2}; Point(4) = {40, -3, 0, 2};
Point(5) = {40, 20, 0, 2}; Point(6) = {0, 20, 0, 2};
Line(1) = {1, 2}; Line(2) = {2, 3}; Line(3) = {3, 4}; Line(4) = {4, 5}; Line(5) = {5, 6}; Line(6) = {6, 1};
Curve Loop(1) = {1, 2, 3, 4, 5, 6}; Plane Surface(1) = {1};
Physical Curve("bottom") = {1}; Physical Curve("top") = {5}; Physical Surface("body") = {1};
""")
    s = _err_scene(str(tmp_path / "m.geo"))
    s["analyses"] = []
    res = run_scene(s)
    assert any("part of the body starts beyond the obstacle line" in w for w in res["warnings"]), res["warnings"]


@pytest.mark.parametrize("degree", [1, 2])
def test_traction_recovery_is_exact_on_its_space(degree):
    """Nodal forces of a traction of the displacement space (P1: linear per edge, P2: quadratic)
    are recovered exactly by the consistent recovery, a linear one also by the P2 vertex fit;
    a uniform pressure loads P2 vertices and mid-side nodes 1 : 2 (interior, equal edges)."""
    from app.systems.gmsh.contact_traction import contact_recovery
    rng = np.random.default_rng(3)
    xv = np.concatenate([[0.0], np.sort(rng.uniform(0, 2, 7)), [2.0]])
    c, s = math.cos(0.3), math.sin(0.3)                        # a straight curve at 0.3 rad
    pts = lambda x: np.column_stack([c * x + 5.0, s * x - 1.0])    # noqa: E731
    edges = np.stack([pts(xv[:-1]), pts(xv[1:])], axis=1)
    xs = np.sort(np.concatenate([xv, 0.5 * (xv[:-1] + xv[1:])])) if degree == 2 else xv
    order = rng.permutation(len(xs))                            # any node order
    rec = contact_recovery(edges, pts(xs[order]), degree)
    t = 2.5
    p = (1.0 + 0.3 * xs - 0.7 * xs ** 2 if degree == 2 else 1.0 + 0.3 * xs)[order]
    r = t * rec.M @ p
    assert rec.M.sum() == pytest.approx(2.0, rel=1e-12)         # length of the curve
    got = rec.tractions(t, r)
    assert got["consistent"][0] == pytest.approx(p, rel=1e-10)
    if degree == 2:
        lin = (1.0 + 0.3 * xs)[order]
        assert rec.tractions(t, t * rec.M @ lin)["vertex_fit"][0] == pytest.approx(lin, rel=1e-10)
        even = np.linspace(0, 2, 9)
        e2 = np.stack([pts(even[:-1]), pts(even[1:])], axis=1)
        x2 = np.linspace(0, 2, 17)
        u = contact_recovery(e2, pts(x2), 2).M @ np.ones(17)
        assert u[2] / u[1] == pytest.approx(0.5, rel=1e-12) and u[1] == pytest.approx(2 * 0.25 / 3, rel=1e-12)


def test_two_materials_in_series_give_the_exact_uniaxial_compliance(tmp_path):
    """Two physical surfaces (E 2 below y = 8, E 10 above), plane stress, held by a symmetry line
    (x) and the bottom (y), nu = 0 (no lateral mismatch), a total force F on the top: uniaxial stress, so the top moves by
    F / (t W) (8 / 2 + 12 / 10) exactly (P1 and P2). The top is the contact curve, 100 below an
    obstacle it never reaches, so its displacement is reported."""
    (tmp_path / "m.geo").write_text("""
Point(1) = {0, 0, 0, 2}; Point(2) = {10, 0, 0, 2}; Point(3) = {10, 8, 0, 2}; Point(4) = {0, 8, 0, 2};
Point(5) = {10, 20, 0, 2}; Point(6) = {0, 20, 0, 2};
Line(1) = {1, 2}; Line(2) = {2, 3}; Line(3) = {3, 4}; Line(4) = {4, 1}; Line(5) = {3, 5}; Line(6) = {5, 6};
Line(7) = {6, 4};
Curve Loop(1) = {1, 2, 3, 4}; Plane Surface(1) = {1}; Curve Loop(2) = {-3, 5, 6, 7}; Plane Surface(2) = {2};
Physical Curve("bottom") = {1}; Physical Curve("sym") = {4, 7}; Physical Curve("top") = {6};
Physical Surface("soft") = {1}; Physical Surface("hard") = {2};
""")
    for degree in (1, 2):
        res = run_scene({"name": "s", "mu": 0.0, "analyses": [], "system": {
            "type": "gmsh", "file": str(tmp_path / "m.geo"), "contact": "top", "prescribed": {"bottom": "y", "sym": "x"},
            "materials": {"soft": {"E": 2.0, "nu": 0.0}, "hard": {"E": 10.0, "nu": 0.0}}, "degree": degree,
            "thickness": 1.5, "obstacle": {"point": [0, 120], "normal": [0, 1]},
            "program": [{"steps": 2, "force": {"top": [0, -3.0]}}]}})
        top = res["states"][-1]["nodes"]
        delta = 3.0 / (1.5 * 10) * (8 / 2.0 + 12 / 10.0)
        assert all(n["status"] == "free" for n in top)
        assert [n["u_N"] + 100.0 for n in top] == pytest.approx([-delta] * len(top), rel=1e-9)


def test_validating_a_gmsh_scene_loads_neither_dolfinx_nor_petsc():
    """Validation reads the user's file with gmsh only (the registry's rule): DOLFINx and PETSc
    are loaded by the run, not by ``load_scene`` / ``validate`` (it used to load both through an
    import of the block mesher)."""
    import subprocess
    import sys
    code = ("import sys, app; app.load_scene('app/scenes/gmsh/block.yaml'); "
            "print(sorted(m for m in ('dolfinx', 'petsc4py') if m in sys.modules))")
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                       cwd=pathlib.Path(__file__).resolve().parents[1])
    assert p.returncode == 0, p.stderr
    assert p.stdout.strip() == "[]", p.stdout
