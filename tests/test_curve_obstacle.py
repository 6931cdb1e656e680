"""A smooth curve of the scene's Gmsh file as the rigid obstacle (``obstacle: {type: curve}``,
app/loading/curve.py, app/systems/gmsh/child_curves.py, docs/curved.md): the curve class against
closed forms (an ellipse, a circle), the same answers as ``type: circle`` for a circle given as a
Gmsh arc, and one-line errors for hostile or mistaken input."""
import math
import pathlib

import numpy as np
import pytest
from conftest import one_error_line, run_cli_here, run_scene
from scipy.optimize import brentq

BLOCK = """L = 80; H = 40; nx = 10; ny = 5;
Point(1) = {0, 0, 0}; Point(2) = {L, 0, 0}; Point(3) = {L, H, 0}; Point(4) = {0, H, 0};
Line(1) = {1, 2}; Line(2) = {2, 3}; Line(3) = {3, 4}; Line(4) = {4, 1};
Curve Loop(1) = {1, 2, 3, 4};
Plane Surface(1) = {1};
Transfinite Curve {1, 3} = nx + 1;
Transfinite Curve {2, 4} = ny + 1;
Transfinite Surface {1} = {1, 2, 3, 4} Right;
Physical Curve("AB") = {1};
Physical Curve("CD") = {3};
Physical Surface("block") = {1};
"""

# a circle arc of radius R, centre (40, -R), through (40, 0), from left to right (body on its left)
ARC = """R = {R};
Point(11) = {{40, -R, 0}}; Point(13) = {{40, 0, 0}};
Point(12) = {{40 - R * Sin(40 * Pi / 180), -R + R * Cos(40 * Pi / 180), 0}};
Point(14) = {{40 + R * Sin(40 * Pi / 180), -R + R * Cos(40 * Pi / 180), 0}};
Circle(11) = {{12, 11, 13}}; Circle(12) = {{13, 11, 14}};
Physical Curve("ob") = {{11, 12}};
"""

# an ellipse arc, semi-axes A (x) and B (y), centre (40, -B), counter-clockwise from 20 to 160 degrees
A, B = 90.0, 50.0
ELLIPSE = f"""a = {A}; b = {B};
Point(21) = {{40, -b, 0}}; Point(24) = {{40 + a, -b, 0}}; Point(25) = {{40, 0, 0}};
Point(23) = {{40 + a * Cos(20 * Pi / 180), -b + b * Sin(20 * Pi / 180), 0}};
Point(22) = {{40 + a * Cos(160 * Pi / 180), -b + b * Sin(160 * Pi / 180), 0}};
Ellipse(21) = {{23, 21, 24, 25}}; Ellipse(22) = {{25, 21, 24, 22}};
Physical Curve("el") = {{21, 22}};
"""


def curve_of(tmp_path, text, name, side):
    from app.loading.curve import SmoothCurve
    from app.systems.gmsh.mesh import model_info, obstacle_samples
    p = tmp_path / "m.geo"
    p.write_text(text)
    info = model_info(p, p.name)
    assert name not in info.curves and info.obstacle_curves[name]["error"] is None
    return SmoothCurve(name, *obstacle_samples(p, name), side, 80.0), info


def ellipse_reference(x):
    """Closest point on the ellipse (40 + A cos t, -B + B sin t), t in (0, pi), by an independent
    bracketed root solve of d/dt |p(t) - x|^2 = 0 on a fine grid; returns (gap outside, normal, kappa)."""
    out = []
    for px, py in x:
        u, v = px - 40.0, py + B
        f = lambda t: -(u - A * math.cos(t)) * A * math.sin(t) + (v - B * math.sin(t)) * B * math.cos(t)  # noqa: E731
        ts = np.linspace(0.1, math.pi - 0.1, 2001)
        fs = np.array([f(t) for t in ts])
        roots = [brentq(f, ts[i], ts[i + 1], xtol=1e-15) for i in np.flatnonzero(np.sign(fs[:-1]) != np.sign(fs[1:]))]
        d = [math.hypot(u - A * math.cos(t), v - B * math.sin(t)) for t in roots]
        t = roots[int(np.argmin(d))]
        nrm = np.array([B * math.cos(t), A * math.sin(t)])
        nrm /= np.linalg.norm(nrm)                                  # outward normal of the ellipse
        g = float(np.dot([u - A * math.cos(t), v - B * math.sin(t)], nrm))
        kappa = A * B / (A**2 * math.sin(t) ** 2 + B**2 * math.cos(t) ** 2) ** 1.5
        out.append((g, nrm, kappa))
    return out


def test_ellipse_against_closed_forms(tmp_path):
    """Gap, outward normal and curvature of the body outside an ellipse (the arc runs
    counter-clockwise: the body is on its right) at points on both sides, against an independent
    root solve: gaps to 1e-10 of the body size (80), normals to 1e-9, curvature to 1e-7 relative."""
    cv, _ = curve_of(tmp_path, BLOCK + ELLIPSE, "el", "right")
    rng = np.random.default_rng(3)
    x = np.column_stack([rng.uniform(0, 80, 40), rng.uniform(-8, 8, 40)])
    ref = ellipse_reference(x)
    g, (t, n), k = cv.gap(x), cv.frames(x), cv.curvatures(x)
    assert np.any(g > 0) and np.any(g < 0)
    for i, (gr, nr, kr) in enumerate(ref):
        assert abs(g[i] - gr) <= 1e-10 * 80
        assert np.allclose(n[i], -nr, atol=1e-9)               # the body's outward normal points into the ellipse
        assert np.allclose(t[i], [-n[i][1], n[i][0]], atol=1e-15)
        assert k[i] == pytest.approx(-kr, rel=1e-7)             # convex for the body: kappa < 0
    top = cv.curvatures(np.array([[40.0, 0.0]]))[0]
    assert top == pytest.approx(-B / A**2, rel=1e-9)


def test_circle_arc_against_circle(tmp_path):
    """A Gmsh circle arc, sampled, against the exact :class:`Circle`: gaps to 1e-12 of the body
    size, frames to 1e-12, curvature to 1e-10, arc coordinate to 1e-11 of the body size; a body
    on the wrong side flips the gap's sign."""
    from app.loading.curved import Circle
    cv, _ = curve_of(tmp_path, BLOCK + ARC.format(R=100.0), "ob", "left")
    ci = Circle([40.0, -100.0], 100.0, "outside", ref=[40.0, 1.0])
    cv.set_reference([40.0, 1.0])
    rng = np.random.default_rng(5)
    x = np.column_stack([rng.uniform(0, 80, 60), rng.uniform(-5, 20, 60)])
    assert np.max(np.abs(cv.gap(x) - ci.gap(x))) <= 1e-12 * 80
    for a, b in zip(cv.frames(x), ci.frames(x)):
        assert np.max(np.abs(a - b)) <= 1e-12
    assert np.max(np.abs(cv.curvatures(x) - ci.curvatures(x))) <= 1e-10 / 100.0
    assert np.max(np.abs(cv.arc(x) - ci.arc(x))) <= 1e-11 * 80
    other, _ = curve_of(tmp_path, BLOCK + ARC.format(R=100.0), "ob", "right")
    assert np.allclose(other.gap(x), -cv.gap(x), atol=1e-12 * 80)


def test_closed_curve_with_its_seam_under_the_body(tmp_path):
    """A whole circle of three arcs whose joint (s = 0 = P) is at the top, under the body: the
    parameter is periodic, so gaps (1e-12 of the body size), normals (1e-10) and the arc coordinate
    (1e-11) match the exact circle across
    the seam and no node is taken for one beyond an end."""
    from app.loading.curved import Circle
    closed = """R = 100; Point(11) = {40, -R, 0}; Point(12) = {40, 0, 0};
Point(13) = {40 + R * Cos(210 * Pi / 180), -R + R * Sin(210 * Pi / 180), 0};
Point(14) = {40 + R * Cos(330 * Pi / 180), -R + R * Sin(330 * Pi / 180), 0};
Circle(11) = {12, 11, 13}; Circle(12) = {13, 11, 14}; Circle(13) = {14, 11, 12};
Physical Curve("ring") = {11, 12, 13};
"""
    cv, _ = curve_of(tmp_path, BLOCK + closed, "ring", "right")       # counter-clockwise: the outside on its right
    assert cv.closed
    ci = Circle([40.0, -100.0], 100.0, "outside", ref=[40.0, 1.0])
    cv.set_reference([40.0, 1.0])
    x = np.column_stack([np.linspace(30, 50, 41), np.linspace(-1, 3, 41)])
    assert np.max(np.abs(cv.gap(x) - ci.gap(x))) <= 1e-12 * 80
    assert np.max(np.abs(cv.frames(x)[1] - ci.frames(x)[1])) <= 1e-10
    assert np.max(np.abs(cv.arc(x) - ci.arc(x))) <= 1e-11 * 80
    assert not np.any(cv.at_end(x))


def _scene(file, obstacle, analyses=("mceip_mu",), drag_steps=30):
    return {"name": "c", "mu": 1.1, "analyses": list(analyses), "settings": {"mcp": {"certify": False}},
            "system": {"type": "gmsh", "file": str(file), "contact": "AB", "prescribed": {"CD": "xy"},
                       "material": {"E": 5.0, "nu": 0.48, "density": 1.2e-9}, "thickness": 9.6,
                       "obstacle": obstacle,
                       "program": [{"name": "press", "steps": 5, "displacement": {"CD": {"translation": [0, -1.0]}}},
                                   {"name": "drag", "steps": drag_steps,
                                    "displacement": {"CD": {"translation": [-3.0, 0]}}}]}}


def _mu(state):
    return sorted(s["value"] for s in state["analyses"]["mceip_mu"]["solutions"])


def test_circle_as_gmsh_curve_gives_the_circle_answers(tmp_path):
    """The 80 x 40 block pressed (displacement control) and dragged on a convex cylinder R = 100:
    given as a Gmsh circle arc (type curve) or as type circle, every state has the same
    classification, reactions to 1e-9 of the state's scale, the same number of critical mu with
    values to 1e-8 relative, and the same necessary-condition eigenvalue (1e-8)."""
    geo = tmp_path / "b.geo"
    geo.write_text(BLOCK + ARC.format(R=100.0))
    an = ("mceip_mu", "necessary")
    a = run_scene(_scene(geo, {"type": "circle", "centre": [40.0, -100.0], "radius": 100.0, "side": "outside"}, an))
    b = run_scene(_scene(geo, {"type": "curve", "physical": "ob", "side": "left"}, an))
    assert a["failures"] == [] == b["failures"] and len(a["states"]) == len(b["states"])
    worst = 0.0
    for sa, sb in zip(a["states"], b["states"]):
        assert sa["classification"] == sb["classification"]
        assert [n["status"] for n in sa["nodes"]] == [n["status"] for n in sb["nodes"]]
        sc = max(abs(n["r_N"]) for n in sa["nodes"]) or 1.0
        for na, nb in zip(sa["nodes"], sb["nodes"]):
            assert abs(na["r_N"] - nb["r_N"]) <= 1e-9 * sc and abs(na["r_T"] - nb["r_T"]) <= 1e-9 * sc
        ma, mb = _mu(sa), _mu(sb)
        assert len(ma) == len(mb) and mb == pytest.approx(ma, rel=1e-8)
        worst = max([worst] + [abs(u - v) / abs(u) for u, v in zip(ma, mb)])
        assert sb["analyses"]["necessary"]["min_eig_K_sym"] == pytest.approx(
            sa["analyses"]["necessary"]["min_eig_K_sym"], rel=1e-8)
        assert sb["curved_contact"]["curvature"] == pytest.approx([-0.01] * len(sb["nodes"]), rel=1e-9)
    assert any(_mu(s) for s in b["states"])
    print("circle as a Gmsh curve: largest relative difference of a critical mu", worst)


def _write(tmp_path, geo_text, obstacle, file_name="b.geo") -> pathlib.Path:
    import yaml
    (tmp_path / file_name).write_text(geo_text)
    scene = _scene(file_name, obstacle)
    p = tmp_path / "scene.yaml"
    p.write_text(yaml.safe_dump(scene))
    return p


CORNER = """Point(31) = {-20, 0, 0}; Point(32) = {40, 0, 0}; Point(33) = {100, -10, 0};
Line(31) = {31, 32}; Line(32) = {32, 33};
Physical Curve("kink") = {31, 32};
"""

WAVY = "Point(40) = {-20, 0, 0};\n" + "".join(
    f"Point({41 + i}) = {{{-20 + 0.3 * (i + 1)}, {-0.0 if i % 2 else -0.29}, 0}};\n" for i in range(400)) + \
    "BSpline(40) = {40:440};\nPhysical Curve(\"wavy\") = {40};\n"


@pytest.mark.parametrize("geo_extra, obstacle, words", [
    (ARC.format(R=100.0), {"type": "curve", "physical": "nothere", "side": "left"},
     ["system.obstacle.physical = 'nothere'", "no physical curve 'nothere'", "ob"]),
    ("", {"type": "curve", "physical": "AB", "side": "left"}, ["system.obstacle.physical = 'AB'", "part of the body"]),
    ("Point(50) = {10, 20, 0}; Point(51) = {70, 20, 0}; Line(50) = {50, 51}; Line{50} In Surface{1};\n"
     "Physical Curve(\"inner\") = {50};\n", {"type": "curve", "physical": "inner", "side": "left"},
     ["system.obstacle.physical = 'inner'", "part of the body"]),
    (CORNER, {"type": "curve", "physical": "kink", "side": "left"},
     ["system.obstacle.physical = 'kink'", "corner", "continuous tangent"]),
    (WAVY, {"type": "curve", "physical": "wavy", "side": "left"},
     ["system.obstacle.physical = 'wavy'", "gmsh evaluations"]),
    (ARC.format(R=100.0), {"type": "curve", "physical": "ob", "side": "outside"},
     ["system.obstacle.side = 'outside'", "left or right"]),
    (ARC.format(R=100.0), {"type": "curve", "physical": "ob", "side": "left", "radius": 3.0},
     ["system.obstacle.radius", "not allowed with type: curve"]),
    (ARC.format(R=100.0), {"type": "curve", "side": "left"}, ["system.obstacle.physical", "missing"]),
])
def test_curve_user_errors_are_one_line(tmp_path, geo_extra, obstacle, words):
    """A missing curve, a curve of the body (on its boundary or embedded in it), a corner, a curve needing too many samples, keys of another type:
    one ``error:`` line naming the key, exit status 2, no traceback."""
    p = _write(tmp_path, BLOCK + geo_extra, obstacle)
    line = one_error_line(run_cli_here("validate", str(p), cwd=tmp_path))
    for w in words:
        assert w in line, line


def test_curve_wrong_side_and_msh_are_one_line(tmp_path):
    """The body on the other side of the curve (found when the body is built: ``run``), and a
    curve named in a .msh file (only its mesh, no geometry): one line each, exit status 2."""
    p = _write(tmp_path, BLOCK + ARC.format(R=100.0), {"type": "curve", "physical": "ob", "side": "right"})
    line = one_error_line(run_cli_here("run", str(p), "-o", str(tmp_path / "out"), "-q", cwd=tmp_path))
    assert "system.obstacle.side = 'right'" in line and "on its left" in line
    from app.systems.gmsh.mesh import gmsh_initialize
    geo = tmp_path / "c.geo"
    geo.write_text(BLOCK + ARC.format(R=100.0))
    gmsh, here = gmsh_initialize()
    try:
        gmsh.model.add("m")
        gmsh.open(str(geo))
        gmsh.model.mesh.generate(2)
        gmsh.write(str(tmp_path / "c.msh"))
        gmsh.model.remove()
    finally:
        if here:
            gmsh.finalize()
    import yaml
    scene = _scene("c.msh", {"type": "curve", "physical": "ob", "side": "left"})
    (tmp_path / "m.yaml").write_text(yaml.safe_dump(scene))
    line = one_error_line(run_cli_here("validate", str(tmp_path / "m.yaml"), cwd=tmp_path))
    assert "system.obstacle.physical = 'ob'" in line and ".geo" in line


@pytest.mark.slow
def test_shipped_curve_examples(tmp_path):
    """app/scenes/gmsh/half_disk_cylinder_curve.yaml (the cylinder of half_disk_cylinder.yaml as a
    Gmsh circle arc) gives that scene's classifications and critical mu (1e-8 relative);
    half_disk_ellipse.yaml reaches gross sliding, records each node's curvature at its contact
    point (between the ellipse's extremes, varying along the contact) and, less convex at the top
    (radius 67.5 against 60 mm), has a larger smallest critical mu than the cylinder."""
    import json
    import re

    from test_gmsh_examples import EX
    out = {}
    for name in ("half_disk_cylinder", "half_disk_cylinder_curve", "half_disk_ellipse"):
        text = re.sub(r"^outputs:.*$", "", (EX / f"{name}.yaml").read_text(), flags=re.M)
        text = re.sub(r"^analyses:.*$", "analyses: [mceip_mu]", text, flags=re.M)
        text = re.sub(r"^settings:.*$", "settings: {mcp: {certify: false}}", text, flags=re.M)
        (tmp_path / f"{name}.yaml").write_text(text)
        for geo in ("half_disk_curved.geo", "half_disk_on_curves.geo"):
            (tmp_path / geo).write_text((EX / geo).read_text())
        p = run_cli_here("run", str(tmp_path / f"{name}.yaml"), "-o", str(tmp_path / name), "-q")
        assert p.returncode == 0, p.stderr
        out[name] = json.loads((tmp_path / name / "results.json").read_text())
    a, b, e = (out[k]["states"] for k in ("half_disk_cylinder", "half_disk_cylinder_curve", "half_disk_ellipse"))
    assert len(a) == len(b)
    for sa, sb in zip(a, b):
        assert sa["classification"] == sb["classification"]
        assert _mu(sb) == pytest.approx(_mu(sa), rel=1e-8)
    assert "gross sliding" in out["half_disk_ellipse"]["path"]["end"] and out["half_disk_ellipse"]["failures"] == []
    k = np.concatenate([s["curved_contact"]["curvature"] for s in e])
    assert np.all(k <= -30 / 45**2 * (1 - 1e-9)) and np.all(k >= -45 / 30**2) and np.ptp(k) > 1e-4
    smallest = lambda states: min(min(_mu(s)) for s in states if _mu(s))   # noqa: E731
    assert smallest(e) > smallest(a)
    print("smallest critical mu: cylinder", smallest(a), "as a Gmsh curve", smallest(b), "ellipse", smallest(e))


def test_a_node_sliding_past_the_end_of_the_curve_ends_the_path(tmp_path):
    """A nearly flat arc (R = 1e4) ending 1 mm beyond the block's left corner; the block, pressed,
    slides 3 mm to the left. The increment that would carry the corner past the arc's end (a
    corner of the obstacle: no normal) ends the path with one reason naming the node and the
    curve; every kept state has the corner node on the arc (x = u_T > the end's x, from the
    geometry)."""
    theta = 0.2349                                   # degrees: the arc's half-angle
    arc = ARC.replace("R = {R};", "R = 10000;").replace("40 * Pi / 180", f"{theta} * Pi / 180").format()
    geo = tmp_path / "b.geo"
    geo.write_text(BLOCK + arc)
    sc = _scene(geo, {"type": "curve", "physical": "ob", "side": "left"}, drag_steps=20)
    sc["mu"] = 0.3
    sc["system"]["program"][1].update({"stop_at_gross_sliding": False,
                                        "displacement": {"CD": {"translation": [-3.0, 0]}}})
    res = run_scene(sc)
    end_x = 40.0 - 1e4 * math.sin(math.radians(theta))          # -0.9968
    assert res["failures"] and res["failures"][0]["analysis"] == "contact increment"
    why = res["failures"][0]["reason"]
    assert "contact node 0" in why and "slid past an end of the curve 'ob'" in why, why
    assert 5 < len(res["states"]) < 26                         # the press and part of the drag were kept
    for st in res["states"]:
        assert st["nodes"][0]["u_T"] > end_x
    assert res["states"][-1]["nodes"][0]["u_T"] < end_x + 0.3   # it was close to the end
