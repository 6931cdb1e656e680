"""Two deformable bodies (``obstacle: {type: body}``, app/systems/gmsh/interface.py): the block on a
plate of its own material and mesh.

- Rigid limit: a plate 1e8 times stiffer than the block gives the rigid line's path and MCEIP-mu
  to 1e-6; the difference falls as 1/E_plate (observed order printed).
- A conforming interface run node-to-node and node-to-segment gives the same results (1e-10).
- Invariance: the whole scene rotated, in m-N-Pa, on 2 ranks.
- Non-matching meshes: the body finer than the plate and the plate finer than the body converge to
  one onset under refinement.
- One-line errors for the keys of an obstacle body.
"""
import math
import pathlib

import numpy as np
import pytest
import yaml
from conftest import results_on_ranks, run_cli_here, run_scene
from test_gmsh_body import assert_same_path


def pair_geo(path: pathlib.Path, nx: int = 8, ny: int = 4, plate_n: int | None = None, angle_deg: float = 0.0,
             scale: float = 1.0, plate: bool = True) -> str:
    """The paper's block (80 x 40 mm, nx x ny cells, one diagonal each) on a plate 10 mm thick as wide
    as the block (plate_n cells along the interface, 2 across), both structured; coordinates rotated
    by ``angle_deg`` about the origin and multiplied by ``scale``. ``plate=False``: the block alone."""
    c, s = math.cos(math.radians(angle_deg)), math.sin(math.radians(angle_deg))

    def pt(i, x, y):
        return f"Point({i}) = {{{scale * (c * x - s * y)!r}, {scale * (s * x + c * y)!r}, 0}};\n"
    text = "".join(pt(i, x, y) for i, (x, y) in enumerate([(0, 0), (80, 0), (80, 40), (0, 40)], 1))
    text += ("Line(1) = {1, 2}; Line(2) = {2, 3}; Line(3) = {3, 4}; Line(4) = {4, 1};\n"
             "Curve Loop(1) = {1, 2, 3, 4}; Plane Surface(1) = {1};\n"
             f"Transfinite Curve {{1, 3}} = {nx + 1}; Transfinite Curve {{2, 4}} = {ny + 1};\n"
             "Transfinite Surface {1} = {1, 2, 3, 4} Right;\n"
             'Physical Curve("AB") = {1}; Physical Curve("CD") = {3}; Physical Surface("block") = {1};\n')
    if plate:
        n = plate_n or nx
        text += "".join(pt(i, x, y) for i, (x, y) in zip(range(11, 15), [(0, -10), (80, -10), (80, 0), (0, 0)]))
        text += ("Line(11) = {11, 12}; Line(12) = {12, 13}; Line(13) = {13, 14}; Line(14) = {14, 11};\n"
                 "Curve Loop(2) = {11, 12, 13, 14}; Plane Surface(2) = {2};\n"
                 f"Transfinite Curve {{11, 13}} = {n + 1}; Transfinite Curve {{12, 14}} = 3;\n"
                 "Transfinite Surface {2} = {11, 12, 13, 14} Right;\n"
                 'Physical Curve("top") = {13}; Physical Curve("bottom") = {11}; Physical Surface("plate") = {2};\n')
    path.write_text(text)
    return str(path)


def pair_scene(file, E_plate=3000.0, pairing="segment", angle_deg=0.0, units=None, rigid=False, steps=100,
               analyses=("mceip_mu",)):
    c, s = math.cos(math.radians(angle_deg)), math.sin(math.radians(angle_deg))
    k = 1e-3 if units == "m-N-Pa-kg-s" else 1.0          # lengths in m
    e = 1e6 if units == "m-N-Pa-kg-s" else 1.0           # stresses in Pa
    rot = lambda v: [k * (c * v[0] - s * v[1]), k * (s * v[0] + c * v[1])]   # noqa: E731
    mat = {"E": 5.0 * e, "nu": 0.48, "density": 1.2e-9 / (k ** 3 * 1e-3 if units else 1.0)}
    obstacle = ({"point": [0.0, 0.0], "normal": rot([0.0, -1.0])} if rigid else
                {"type": "body", "surface": "plate", "contact": "top", "held": ["bottom"], "pairing": pairing,
                 "material": {"E": E_plate * e, "nu": 0.35, "density": mat["density"]}})
    system = {"type": "gmsh", "file": str(file), "contact": "AB", "prescribed": {"CD": "xy"}, "material": mat,
              "thickness": 9.6 * k, "obstacle": obstacle,
              "program": [{"name": "press", "steps": 10, "displacement": {"CD": {"translation": rot([0.0, -1.0])}},
                           "until": {"normal_force": 55.0}},
                          {"name": "drag", "steps": steps, "displacement": {"CD": {"translation": rot([-10.0, 0.0])}}}]}
    out = {"name": "pair", "system": system, "mu": 1.1, "analyses": list(analyses)}
    if units:
        out["units"] = units
    return out


def final_mu(res) -> float:
    return min(s["value"] for s in res["states"][-1]["analyses"]["mceip_mu"]["solutions"])


@pytest.fixture(scope="module")
def geo(tmp_path_factory):
    d = tmp_path_factory.mktemp("pair")
    return {"pair": pair_geo(d / "pair.geo"), "block": pair_geo(d / "block.geo", plate=False), "dir": d}


@pytest.fixture(scope="module")
def rigid(geo):
    return run_scene(pair_scene(geo["block"], rigid=True))


def test_a_plate_1e8_times_stiffer_is_the_rigid_line(geo, rigid):
    got = run_scene(pair_scene(geo["pair"], E_plate=5e8))
    assert_same_path(rigid, got, rtol=1e-6, reactions=1e-6)
    assert final_mu(got) == pytest.approx(final_mu(rigid), rel=1e-6)
    for a, b in zip(rigid["states"], got["states"]):
        assert [n["u_T"] for n in b["nodes"]] == pytest.approx([n["u_T"] for n in a["nodes"]], abs=1e-6)


def test_the_rigid_limit_converges_as_one_over_the_plates_modulus(geo, rigid):
    """The final onset and the press's reactions differ from the rigid line's by O(E_body / E_plate):
    observed order 1 over two decades (same classifications once the plate is stiff enough)."""
    ref_r = np.array([n["r_N"] for n in rigid["states"][9]["nodes"]])
    errs_mu, errs_r = [], []
    for E in (5e3, 5e4, 5e5):
        got = run_scene(pair_scene(geo["pair"], E_plate=E))
        errs_mu.append(abs(final_mu(got) - final_mu(rigid)))
        errs_r.append(np.abs(np.array([n["r_N"] for n in got["states"][9]["nodes"]]) - ref_r).max())
    order_mu = [math.log10(errs_mu[i] / errs_mu[i + 1]) for i in range(2)]
    order_r = [math.log10(errs_r[i] / errs_r[i + 1]) for i in range(2)]
    print(f"rigid limit: |mu - mu_rigid| = {errs_mu}, observed orders {order_mu}; press reactions {errs_r}, "
          f"orders {order_r}")
    assert all(0.9 < o < 1.1 for o in order_mu + order_r), (order_mu, order_r)


@pytest.mark.parametrize("degree", [1, 2])
def test_node_to_node_equals_node_to_segment_on_a_conforming_interface(geo, degree):
    a, b = pair_scene(geo["pair"], pairing="node"), pair_scene(geo["pair"], pairing="segment")
    a["system"]["degree"] = b["system"]["degree"] = degree
    a, b = run_scene(a), run_scene(b)
    assert_same_path(a, b, rtol=1e-10, reactions=1e-10)
    assert final_mu(a) == pytest.approx(final_mu(b), rel=1e-10)
    assert "node-to-node" in a["system"] and "node-to-segment" in b["system"]


@pytest.mark.parametrize("angle", [30.0, -90.0])
def test_rotating_the_whole_scene_changes_nothing(geo, angle):
    ref = run_scene(pair_scene(geo["pair"]))
    f = pair_geo(geo["dir"] / f"rot{angle:g}.geo", angle_deg=angle)
    got = run_scene(pair_scene(f, angle_deg=angle))
    assert_same_path(ref, got, rtol=1e-10, reactions=1e-10)


def test_metres_newtons_pascals_give_the_same_onsets(geo):
    ref = run_scene(pair_scene(geo["pair"]))
    f = pair_geo(geo["dir"] / "metres.geo", scale=1e-3)
    got = run_scene(pair_scene(f, units="m-N-Pa-kg-s"))
    assert_same_path(ref, got, rtol=1e-10, reactions=1e-10)


def test_two_ranks_give_the_one_rank_numbers(tmp_path):
    f = pair_geo(tmp_path / "p.geo", nx=10, ny=5, plate_n=7, angle_deg=20.0)
    (tmp_path / "s.yaml").write_text(yaml.safe_dump(pair_scene("p.geo", angle_deg=20.0, steps=50,
                                                               analyses=["necessary", "mceip_mu"])))
    out = results_on_ranks(tmp_path / "s.yaml", tmp_path)
    assert f
    assert_same_path(out[1], out[2], rtol=1e-10, reactions=1e-10)


def test_non_matching_meshes_converge_to_one_onset_whichever_is_finer(tmp_path):
    """Block n x n/2 on a plate of 3n/2 cells, and the block 3n/2 x 3n/4 on a plate of n: the two
    onsets approach each other as n doubles."""
    gaps = []
    for n in (8, 16, 32):
        m = 3 * n // 2
        a = run_scene(pair_scene(pair_geo(tmp_path / f"a{n}.geo", nx=n, ny=n // 2, plate_n=m), steps=50))
        b = run_scene(pair_scene(pair_geo(tmp_path / f"b{n}.geo", nx=m, ny=m // 2, plate_n=n), steps=50))
        gaps.append(abs(final_mu(a) - final_mu(b)))
    print(f"non-matching: |mu(body finer) - mu(plate finer)| = {gaps}")
    assert gaps[2] < gaps[1] < gaps[0]


@pytest.mark.parametrize("obstacle, key, words", [
    ({"surface": "nowhere"}, "system.obstacle.surface", "no physical surface 'nowhere'"),
    ({"contact": "AB"}, "system.obstacle.contact", "the body's own contact curve"),
    ({"held": ["top"]}, "system.obstacle.held", "a contact curve cannot be held"),
    ({"held": ["CD"]}, "system.obstacle.held", "also under prescribed"),
    ({"material": None}, "system.obstacle.material", "missing"),
    ({"point": [1, 0]}, "system.obstacle.point", "not allowed with type: body"),
])
def test_an_obstacle_body_s_keys_are_checked_in_one_line(geo, tmp_path, obstacle, key, words):
    s = pair_scene(geo["pair"])
    s["system"]["obstacle"].update(obstacle)
    if obstacle.get("material", 0) is None:
        del s["system"]["obstacle"]["material"]
    (tmp_path / "s.yaml").write_text(yaml.safe_dump(s))
    p = run_cli_here("validate", str(tmp_path / "s.yaml"))
    assert p.returncode == 2
    line = p.stderr.strip()
    assert len(line.splitlines()) == 1 and key in line and words in line, line


def test_a_kinked_obstacle_contact_curve_is_refused_in_one_line(tmp_path):
    """A curved obstacle-body curve needs a continuous tangent: a plate whose top kinks by 0.5 mm
    (1.43 degrees) is refused."""
    text = pathlib.Path(pair_geo(tmp_path / "p.geo", plate=False)).read_text()
    text += ("Point(11) = {0, -10, 0}; Point(12) = {80, -10, 0}; Point(13) = {80, 0, 0}; Point(14) = {0, 0, 0};\n"
             "Point(15) = {40, -0.5, 0};\n"
             "Line(11) = {11, 12}; Line(12) = {12, 13}; Line(13) = {13, 15}; Line(15) = {15, 14}; Line(14) = {14, 11};\n"
             "Curve Loop(2) = {11, 12, 13, 15, 14}; Plane Surface(2) = {2};\n"
             'Physical Curve("top") = {13, 15}; Physical Curve("bottom") = {11}; Physical Surface("plate") = {2};\n')
    (tmp_path / "p.geo").write_text(text)
    (tmp_path / "s.yaml").write_text(yaml.safe_dump(pair_scene("p.geo")))
    p = run_cli_here("run", str(tmp_path / "s.yaml"), "-o", str(tmp_path / "o"), "-q")
    line = p.stderr.strip()
    assert p.returncode == 2 and len(line.splitlines()) == 1, p.stderr
    assert "system.obstacle.contact = 'top'" in line and "continuous tangent" in line, line
    assert not (tmp_path / "o").exists()


EX = pathlib.Path(__file__).resolve().parents[1] / "app" / "scenes" / "gmsh"


@pytest.mark.parametrize("name", ["block_on_epoxy.yaml", "rubber_on_rubber.yaml"])
def test_shipped_two_body_scenes_prove_every_onset_and_check_re_verifies_them(tmp_path, name):
    import json
    out = tmp_path / "out"
    p = run_cli_here("run", str(EX / name), "-o", str(out), "-q", "--set", "analyses=[mceip_mu]",
                     "--set", "outputs.plots=false", "--set", "outputs.report=false")
    assert p.returncode == 0, p.stderr
    res = json.loads((out / "results.json").read_text())
    with_onset = [st for st in res["states"] if st["analyses"].get("mceip_mu", {}).get("solutions")]
    assert with_onset
    for st in with_onset:
        assert st["analyses"]["mceip_mu"]["onset"]["proven"] is True, st["index"]
    # both bodies drawn: the screenshots' mesh holds the obstacle's cells too
    assert any(f.name.startswith("mode_") for f in (out / "screenshots").glob("*.png"))
    c = run_cli_here("check", str(out))
    assert c.returncode == 0, c.stdout + c.stderr
    assert "re-verified from the stored pencils" in c.stdout


@pytest.mark.parametrize("degree", [1, 2])
def test_the_flexibility_is_b_k_inverse_b_transposed_of_the_two_bodies(tmp_path, degree):
    """W of the change of variables equals B K^-1 B^T computed here from the two bodies' stiffness
    in their own DOFs (the same file run with the plate as a second surface of one body on a rigid
    line, the plate's bottom prescribed), B the relative displacements with this test's own
    pairing (P1: linear, P2: quadratic interpolation on the plate's top): a non-matching interface,
    1e-10."""
    import scipy.sparse.linalg
    from mpi4py import MPI

    from app.common.stages import Stages
    from app.linalg import to_scipy
    from app.scene.schema import parse_scene
    from app.systems.gmsh.path import build
    f = pair_geo(tmp_path / "p.geo", nx=6, ny=3, plate_n=4)
    two = pair_scene(f)
    one = pair_scene(f, rigid=True)
    one["system"]["prescribed"]["bottom"] = "xy"
    one["system"]["materials"] = {"block": one["system"].pop("material"),
                                  "plate": two["system"]["obstacle"]["material"]}
    one["system"]["degree"] = two["system"]["degree"] = degree
    with build(parse_scene(two).system, MPI.COMM_WORLD, Stages()) as a, \
            build(parse_scene(one).system, MPI.COMM_WORLD, Stages()) as b:
        W_app = a.flexibility.W
        ops = b.fields.ops
        K = to_scipy(b.K).tocsc()
        d = ops.field_data
        reduced = {int(loc): i for i, loc in enumerate(d.kept_local)}       # local unrolled DOF -> reduced
        contact = {tuple(p) for p in ops.contact_dofs.tolist()}
        # the plate's top: the nodes on y = 0 that are not the block's contact nodes (both are there)
        top = sorted((float(x[0]), reduced[2 * blk], reduced[2 * blk + 1]) for blk, x in enumerate(d.dof_x)
                     if abs(x[1]) < 1e-12 and 2 * blk in reduced
                     and (reduced[2 * blk], reduced[2 * blk + 1]) not in contact)
        assert len(top) == 4 * degree + 1
        n = len(ops.contact_xy)
        B = np.zeros((2 * n, K.shape[0]))
        xs = np.array([t[0] for t in top[::degree]])          # the segments' ends
        for a_, (x, (dT, dN)) in enumerate(zip(ops.contact_xy[:, 0], ops.contact_dofs)):
            B[2 * a_, dT] = 1.0                   # the rigid line's frame: T = +x, N = -y
            B[2 * a_ + 1, dN] = 1.0
            j = min(max(int(np.searchsorted(xs, x)) - 1, 0), len(xs) - 2)
            xi = (x - xs[j]) / (xs[j + 1] - xs[j])
            ws = (1 - xi, xi) if degree == 1 else ((1 - xi) * (1 - 2 * xi), 4 * xi * (1 - xi), xi * (2 * xi - 1))
            for w, (_, mx, my) in zip(ws, top[degree * j:degree * j + degree + 1]):
                B[2 * a_, mx] -= w
                B[2 * a_ + 1, my] += w            # N = -y: minus the obstacle point's -u_y
        W = B @ scipy.sparse.linalg.splu(K).solve(B.T)
    assert W_app.shape == W.shape
    assert np.max(np.abs(W_app - W)) <= 1e-10 * np.max(np.abs(W))


def seat_geo(path: pathlib.Path, radius: float = 60.0, angle_deg: float = 0.0, n: int = 21, disk: bool = True,
             seat: bool = True) -> str:
    """A half disk of radius 20 (centre (0, 20), its arc touching the origin, the flat side on top) in
    a seat whose top is the arc of ``radius`` about (0, radius) through the origin, its bottom held;
    every part a structured (transfinite) mesh with ``n`` nodes on each half arc, so that a rotation
    by ``angle_deg`` about the origin rotates the mesh. ``radius`` 60: a plate 60 mm wide, 10 mm
    below the origin; ``radius`` 20: a ring of outer radius 30 around the disk, held on its outer
    arc (the interface conforming, touching everywhere)."""
    c, s = math.cos(math.radians(angle_deg)), math.sin(math.radians(angle_deg))

    def pt(i, x, y):
        return f"Point({i}) = {{{c * x - s * y!r}, {s * x + c * y!r}, 0}};\n"
    text = ""
    if disk:
        text += pt(1, 0, 20) + pt(2, -20, 20) + pt(3, 0, 0) + pt(4, 20, 20) + pt(5, 0, 20)
        text += ("Circle(1) = {2, 1, 3}; Circle(2) = {3, 1, 4}; Line(3) = {4, 5}; Line(4) = {5, 2};\n"
                 f"Curve Loop(1) = {{1, 2, 3, 4}}; Plane Surface(1) = {{1}}; Transfinite Curve {{1, 2, 3, 4}} = {n};\n"
                 "Transfinite Surface {1} = {2, 3, 4, 5};\n"
                 'Physical Curve("arc") = {1, 2}; Physical Curve("top") = {3, 4}; Physical Surface("disk") = {1};\n')
    if seat:
        if radius == 20.0:        # a ring: inner arc 20 (the disk's), outer arc 30, both about (0, 20)
            top, outer = [(-20, 20), (0, 0), (20, 20)], [(-30, 20), (0, -10), (30, 20)]
            bottom = "Circle(13) = {18, 11, 19}; Circle(14) = {19, 11, 20};"
        else:
            y_end = radius - math.sqrt(radius * radius - 900.0)
            top, outer = [(-30, y_end), (0, 0), (30, y_end)], [(-30, -10), (0, -10), (30, -10)]
            bottom = "Line(13) = {18, 19}; Line(14) = {19, 20};"
        # 11 the arc's centre; 12, 13, 14 the top arc's left end, bottom, right end; 18, 19, 20 below them
        text += pt(11, 0, radius) + "".join(pt(i, *p) for i, p in zip((12, 13, 14), top))
        text += "".join(pt(i, *p) for i, p in zip((18, 19, 20), outer))
        text += ("Circle(11) = {12, 11, 13}; Circle(12) = {13, 11, 14}; " + bottom + "\n"
                 "Line(15) = {18, 12}; Line(16) = {13, 19}; Line(17) = {20, 14};\n"
                 "Curve Loop(2) = {-15, 13, -16, -11}; Plane Surface(2) = {2};\n"
                 "Curve Loop(3) = {16, 14, 17, -12}; Plane Surface(3) = {3};\n"
                 f"Transfinite Curve {{11, 12, 13, 14}} = {n}; Transfinite Curve {{15, 16, 17}} = 5;\n"
                 "Transfinite Surface {2} = {12, 18, 19, 13}; Transfinite Surface {3} = {13, 19, 20, 14};\n"
                 'Physical Curve("seat_top") = {11, 12}; Physical Curve("seat_bottom") = {13, 14};\n'
                 'Physical Surface("seat") = {2, 3};\n')
    path.write_text(text)
    return str(path)


def seat_scene(file, E_seat=5e3, pairing="segment", angle_deg=0.0, circle=None, steps=30):
    c, s = math.cos(math.radians(angle_deg)), math.sin(math.radians(angle_deg))
    rot = lambda v: [c * v[0] - s * v[1], s * v[0] + c * v[1]]   # noqa: E731
    obstacle = ({"type": "circle", "centre": rot([0.0, circle]), "radius": circle, "side": "inside"} if circle else
                {"type": "body", "surface": "seat", "contact": "seat_top", "held": ["seat_bottom"], "pairing": pairing,
                 "material": {"E": E_seat, "nu": 0.3, "density": 1.2e-9}})
    return {"name": "seat", "mu": 1.1, "analyses": ["mceip_mu"],
            "system": {"type": "gmsh", "file": str(file), "contact": "arc", "prescribed": {"top": "xy"},
                       "material": {"E": 5.0, "nu": 0.3, "density": 1.2e-9}, "thickness": 10.0, "obstacle": obstacle,
                       "program": [{"name": "press", "steps": 5, "until": {"normal_force": 20.0},
                                    "displacement": {"top": {"translation": rot([0.0, -1.0])}}},
                                   {"name": "shear", "steps": steps,
                                    "displacement": {"top": {"translation": rot([-3.0, 0.0])}}}]}}


def test_a_stiff_curved_seat_is_the_rigid_circle_and_converges_at_order_one(tmp_path):
    """The half disk in an elastic seat of radius 60 (a curved contact curve: its smooth geometry,
    frames and curvature terms, as a rigid curve's) against the rigid circle of the same radius:
    identical at 1e8 times the disk's modulus (1e-6), the difference falling as 1/E."""
    rigid = run_scene(seat_scene(seat_geo(tmp_path / "disk.geo", seat=False), circle=60.0))
    pair = seat_geo(tmp_path / "seat.geo")
    got = run_scene(seat_scene(pair, E_seat=5e8))
    assert "curved" in got["system"]
    assert_same_path(rigid, got, rtol=1e-6, reactions=1e-6, below=11.0)
    ref = np.array([n["r_N"] for n in rigid["states"][4]["nodes"]])
    errs = []
    for E in (5e3, 5e4, 5e5):
        r = run_scene(seat_scene(pair, E_seat=E))
        errs.append(np.abs(np.array([n["r_N"] for n in r["states"][4]["nodes"]]) - ref).max())
    orders = [math.log10(errs[i] / errs[i + 1]) for i in range(2)]
    print(f"curved seat, rigid limit: press reactions {errs}, observed orders {orders}")
    assert all(0.9 < o < 1.1 for o in orders), orders


def test_a_conforming_curved_interface_node_to_node_equals_node_to_segment(tmp_path):
    """The half disk in a seat of its own radius, both arcs with the same nodes (touching everywhere
    at the start): node-to-node and node-to-segment give the same path and onsets (1e-10)."""
    f = seat_geo(tmp_path / "fit.geo", radius=20.0)
    a = run_scene(seat_scene(f, pairing="node"))
    b = run_scene(seat_scene(f, pairing="segment"))
    assert_same_path(a, b, rtol=1e-10, reactions=1e-10)
    assert a["states"][0]["classification"]["free"] < len(a["states"][0]["nodes"])


def test_rotating_a_curved_pair_changes_nothing(tmp_path):
    ref = run_scene(seat_scene(seat_geo(tmp_path / "s0.geo")))
    got = run_scene(seat_scene(seat_geo(tmp_path / "s30.geo", angle_deg=30.0), angle_deg=30.0))
    assert_same_path(ref, got, rtol=1e-8, reactions=1e-8)


def test_moving_the_obstacle_by_its_held_curve_is_moving_the_body_the_other_way(geo, rigid):
    """CD held fixed and a stiff plate pushed up to 55 N and dragged right by its bottom: the same
    relative motion as the rigid-line scene's CD pressed and dragged left, so the same states."""
    s = pair_scene(geo["pair"], E_plate=5e8)
    s["system"]["program"] = [
        {"name": "press", "steps": 10, "displacement": {"bottom": {"translation": [0.0, 1.0]}},
         "until": {"normal_force": 55.0}},
        {"name": "drag", "steps": 100, "displacement": {"bottom": {"translation": [10.0, 0.0]}}}]
    got = run_scene(s)
    assert_same_path(rigid, got, rtol=1e-6, reactions=1e-6)
    assert got["states"][-1]["load"]["parameters"]["motion.bottom.tx"] == pytest.approx(
        -rigid["states"][-1]["load"]["parameters"]["motion.CD.tx"], rel=1e-12)


WAVY_TOP = """Point(1) = {0, 0, 0, 4}; Point(2) = {80, 0, 0, 4};
""" + "".join(f"Point({10 + i}) = {{{80 - 0.2 * i}, {40 + (0.25 if i % 2 else -0.25)}, 0, 4}};\n" for i in range(401)) + """
Line(1) = {1, 2}; Line(2) = {2, 10}; BSpline(3) = {10:410}; Line(4) = {410, 1};
Curve Loop(1) = {1, 2, 3, 4}; Plane Surface(1) = {1};
Physical Curve("AB") = {1}; Physical Curve("CD") = {3}; Physical Surface("block") = {1};
"""


def test_a_wavy_curve_of_the_body_is_sampled_within_its_budget_and_stops_nothing(tmp_path):
    """Every physical curve of a .geo is sampled (a possible obstacle-body contact curve), within a
    budget of gmsh evaluations of its own: a curve that exhausts it (a 400-wiggle spline, here the
    body's own top) is recorded as not sampled and the scene validates and runs as before; only
    naming it an obstacle body's contact curve would report it (one line)."""
    import json
    import time

    from app.systems.gmsh.mesh import model_info
    (tmp_path / "w.geo").write_text(WAVY_TOP)
    t0 = time.perf_counter()
    info = model_info(tmp_path / "w.geo", "w.geo")
    assert time.perf_counter() - t0 < 120
    assert "gmsh evaluations" in (info.boundary_curves["CD"]["error"] or "")
    assert info.boundary_curves["AB"]["error"] is None
    s = pair_scene("w.geo", rigid=True, steps=2)
    (tmp_path / "s.yaml").write_text(yaml.safe_dump(s))
    p = run_cli_here("run", str(tmp_path / "s.yaml"), "-o", str(tmp_path / "o"), "-q")
    assert p.returncode == 0, p.stderr
    assert json.loads((tmp_path / "o" / "results.json").read_text())["states"]
