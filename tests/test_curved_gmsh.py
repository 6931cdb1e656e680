"""A Gmsh body on a rigid circle (app/loading/curved.py, docs/method.md section 8): the loading path
with the exact gap against the straight line as R -> infinity (with the observed rate), rotation
about the circle's centre, and units."""
import math
import re

import numpy as np
import pytest
from conftest import run_cli_here, run_scene

GEO = """s = {scale};
L = 80 * s; H = 40 * s; nx = 10; ny = 5;
Point(1) = {{{x0}, {y0}, 0}}; Point(2) = {{{x1}, {y1}, 0}}; Point(3) = {{{x2}, {y2}, 0}}; Point(4) = {{{x3}, {y3}, 0}};
Line(1) = {{1, 2}}; Line(2) = {{2, 3}}; Line(3) = {{3, 4}}; Line(4) = {{4, 1}};
Curve Loop(1) = {{1, 2, 3, 4}};
Plane Surface(1) = {{1}};
Transfinite Curve {{1, 3}} = nx + 1;
Transfinite Curve {{2, 4}} = ny + 1;
Transfinite Surface {{1}} = {{1, 2, 3, 4}} Right;
Physical Curve("AB") = {{1}};
Physical Curve("CD") = {{3}};
Physical Surface("block") = {{1}};
"""


def write_geo(path, scale=1.0, angle_deg=0.0, about=(0.0, 0.0)):
    """The 80 x 40 block (10 x 5 cells, scaled), rotated by ``angle_deg`` about ``about``."""
    c, s = math.cos(math.radians(angle_deg)), math.sin(math.radians(angle_deg))
    corners = np.array([[0, 0], [80, 0], [80, 40], [0, 40]]) * scale
    p = np.asarray(about) + (corners - np.asarray(about)) @ np.array([[c, s], [-s, c]])
    kw = {f"{a}{i}": repr(float(p[i, j])) for i in range(4) for j, a in enumerate("xy")}
    path.write_text(GEO.format(scale=scale, **kw))
    return str(path)


def scene(file, obstacle, scale=1.0, angle_deg=0.0, units="mm-N-MPa-tonne-s", analyses=("mceip_mu",), press=None):
    """``press``: None, force control to 55 N (regula falsi: the path is determined to 1e-10 of the
    force); a depth: displacement control (the path is then determined to round-off)."""
    c, s = math.cos(math.radians(angle_deg)), math.sin(math.radians(angle_deg))
    rot = lambda v: [scale * (c * v[0] - s * v[1]), scale * (s * v[0] + c * v[1])]   # noqa: E731
    E, rho = (5.0, 1.2e-9) if units.startswith("mm") else (5.0e6, 1.2e3)
    # the path is what these tests check: no exact proofs of the quadratic MCEIP-mu (tested in
    # tests/test_mceip_mu_quadratic.py and tests/test_curved_particles.py), the enumeration only
    return {"name": "c", "units": units, "mu": 1.1, "analyses": list(analyses), "settings": {"mcp": {"certify": False}},
            "system": {"type": "gmsh", "file": file, "contact": "AB", "prescribed": {"CD": "xy"},
                       "material": {"E": E, "nu": 0.48, "density": rho}, "thickness": 9.6 * scale,
                       "obstacle": obstacle,
                       "program": [{"name": "press", "steps": 5, "displacement": {"CD": {"translation": rot([0, -1])}},
                                    "until": {"normal_force": 55.0}} if press is None else
                                   {"name": "press", "steps": 5, "displacement": {"CD": {"translation": rot([0, -press])}}},
                                   {"name": "drag", "steps": 60, "displacement": {"CD": {"translation": rot([-6.0, 0])}}}]}}


def circle(R, side="outside", centre_x=40.0):
    return {"type": "circle", "centre": [centre_x, -R if side == "outside" else R], "radius": R, "side": side}


def mu_values(state):
    return sorted(s["value"] for s in state["analyses"]["mceip_mu"]["solutions"])


@pytest.fixture(scope="module")
def geo(tmp_path_factory):
    return write_geo(tmp_path_factory.mktemp("curved") / "b.geo")


@pytest.fixture(scope="module")
def flat(geo):
    return run_scene(scene(geo, {"type": "line"}, analyses=("mceip_mu", "necessary")))


def test_flat_limit_R_1e12_L(geo, flat):
    """R = 1e12 L below AB: every state's classification, reactions (1e-8 of the state's scale) and
    critical mu values (1e-8) are the straight line's; each increment reports its violation."""
    got = run_scene(scene(geo, circle(1e12 * 80.0), analyses=("mceip_mu", "necessary")))
    assert got["failures"] == [] and got["path"]["end"] == flat["path"]["end"]
    assert len(got["states"]) == len(flat["states"])
    for a, b in zip(flat["states"], got["states"]):
        assert [n["status"] for n in a["nodes"]] == [n["status"] for n in b["nodes"]]
        assert [n["sign"] for n in a["nodes"]] == [n["sign"] for n in b["nodes"]]
        sc = max(abs(n["r_N"]) for n in a["nodes"])
        for na, nb in zip(a["nodes"], b["nodes"]):
            assert abs(na["r_N"] - nb["r_N"]) <= 1e-8 * sc and abs(na["r_T"] - nb["r_T"]) <= 1e-8 * sc
        assert mu_values(b) == pytest.approx(mu_values(a), rel=1e-8)
        assert b["analyses"]["necessary"]["min_eig_K_sym"] == pytest.approx(a["analyses"]["necessary"]["min_eig_K_sym"],
                                                                             rel=1e-8)
        assert b["contact_solve"]["violation"] <= 1e-9
        assert b["curved_contact"]["linearisations"] >= 1
    assert any(mu_values(s) for s in got["states"])


def test_convergence_as_R_grows(geo, flat):
    """R = 10^2, 10^3, 10^4 L: the end-of-press reactions and the last state's critical mu converge
    to the line's like 1/R (observed rates printed)."""
    k_press = 4
    ref_r = np.array([n["r_N"] for n in flat["states"][k_press]["nodes"]])
    ref_mu = mu_values(flat["states"][-1])
    Rs = [80.0 * 1e2, 80.0 * 1e3, 80.0 * 1e4]
    err_r, err_mu = [], []
    for R in Rs:
        got = run_scene(scene(geo, circle(R)))
        r = np.array([n["r_N"] for n in got["states"][k_press]["nodes"]])
        err_r.append(float(np.max(np.abs(r - ref_r)) / np.max(np.abs(ref_r))))
        err_mu.append(abs(mu_values(got["states"][-1])[0] - ref_mu[0]) / ref_mu[0])
    rate_r = [math.log10(err_r[i] / err_r[i + 1]) for i in range(2)]
    rate_mu = [math.log10(err_mu[i] / err_mu[i + 1]) for i in range(2)]
    print(f"R/L = 1e2, 1e3, 1e4: reactions {err_r} (rate {rate_r}), last mu {err_mu} (rate {rate_mu})")
    assert err_r[-1] < 5e-3 and err_mu[-1] < 1e-4         # R = 1e4 L (the rate is the check)
    assert all(0.8 < q < 1.2 for q in rate_r + rate_mu)


@pytest.fixture(scope="module")
def moderate(geo):
    return run_scene(scene(geo, circle(400.0), analyses=("mceip_mu", "necessary", "sufficient"), press=0.6))


def test_rotation_about_the_centre(tmp_path, moderate):
    """The body and the motions rotated by 30 degrees about the circle's centre: the same
    classifications and critical values (1e-10 relative). Displacement control: with force control
    the path itself is only determined to the force tolerance (1e-10, app/loading/program.py)."""
    centre = (40.0, -400.0)
    f = write_geo(tmp_path / "r.geo", angle_deg=30.0, about=centre)
    got = run_scene(scene(f, circle(400.0), angle_deg=30.0, analyses=("mceip_mu", "necessary", "sufficient"), press=0.6))
    _same(moderate, got, 1e-10)


def test_si_units(tmp_path, moderate):
    f = write_geo(tmp_path / "m.geo", scale=1e-3)
    ob = {"type": "circle", "centre": [0.04, -0.4], "radius": 0.4, "side": "outside"}
    got = run_scene(scene(f, ob, scale=1e-3, units="m-N-Pa-kg-s", analyses=("mceip_mu", "necessary", "sufficient"),
                          press=0.6))
    _same(moderate, got, 1e-10)


def _same(a_res, b_res, rel):
    assert len(a_res["states"]) == len(b_res["states"])
    n = 0
    for a, b in zip(a_res["states"], b_res["states"]):
        assert [x["status"] for x in a["nodes"]] == [x["status"] for x in b["nodes"]]
        assert [x["sign"] for x in a["nodes"]] == [x["sign"] for x in b["nodes"]]
        assert mu_values(b) == pytest.approx(mu_values(a), rel=rel)
        n += len(mu_values(a))
        for name in ("necessary", "sufficient"):
            if name in a["analyses"]:
                assert b["analyses"][name]["satisfied"] == a["analyses"][name]["satisfied"]
    assert n > 0


def test_fields_on_a_circle_are_the_rotated_fields(tmp_path):
    """With the fields stage: the displacement fields reproduce the states' contact displacements
    (reactions rotated from the contact frames), and the scene rotated about the centre writes the
    rotated displacement, reaction and mode fields (the frame rotations of fields.py)."""
    from scipy.spatial import cKDTree
    from test_fields_any_geometry import _run
    outputs = {"paraview": True, "states": ["final", "first_mceip_mu"], "screenshots": {"resolution": [320, 200]}}
    a = scene(write_geo(tmp_path / "a.geo"), circle(400.0), press=0.6)
    b = scene(write_geo(tmp_path / "b.geo", angle_deg=30.0, about=(40.0, -400.0)), circle(400.0), angle_deg=30.0, press=0.6)
    for d in (a, b):
        d["outputs"] = outputs
        d["system"]["program"][1]["steps"] = 20         # to the first slip, before gross sliding
    ra, fa = _run(a, tmp_path / "oa")
    rb, fb = _run(b, tmp_path / "ob")
    assert ra["outputs"]["contact_displacement_check"] < 1e-10 and rb["outputs"]["contact_displacement_check"] < 1e-10
    c, s = math.cos(math.radians(30.0)), math.sin(math.radians(30.0))
    Q = np.array([[c, -s], [s, c]])
    centre = np.array([40.0, -400.0])
    dist, perm = cKDTree((fa["points"] - centre) @ Q.T + centre).query(fb["points"])
    assert dist.max() < 1e-9 * 80
    for key in ("state_u", "mode_v"):
        assert fa[key].shape == fb[key].shape and fa[key].size
        ref = fa[key][:, perm] @ Q.T
        assert np.abs(fb[key] - ref).max() <= 1e-8 * np.abs(ref).max(), key


@pytest.mark.mpi
def test_same_numbers_on_two_ranks(tmp_path):
    """The exact-gap path and the curved pencils (rotated K, geometric terms, quadratic MCEIP-mu)
    give the same numbers on 1 and 2 MPI ranks."""
    import yaml
    from conftest import results_on_ranks
    write_geo(tmp_path / "b.geo", angle_deg=20.0, about=(40.0, -400.0))
    s = scene("b.geo", circle(400.0), angle_deg=20.0, analyses=("necessary", "mceip_mu"), press=0.6)
    s["system"]["program"][1]["steps"] = 30
    (tmp_path / "s.yaml").write_text(yaml.safe_dump(s))
    out = results_on_ranks(tmp_path / "s.yaml", tmp_path)
    _same(out[1], out[2], 1e-10)
    for x, y in zip(out[1]["states"], out[2]["states"]):
        assert y["analyses"]["necessary"]["min_eig_K_sym"] == pytest.approx(x["analyses"]["necessary"]["min_eig_K_sym"],
                                                                             rel=1e-10)


@pytest.mark.parametrize("side", ["outside", "inside"])
def test_half_disk_on_a_circle_against_hertz(tmp_path, side):
    """The frictionless half-disk of app/scenes/gmsh/half_disk.yaml (R1 = 20 mm, h = 0.04 mm at the
    contact) pressed with 10 N/mm on a rigid circle of radius R2 = 60 mm: Hertz's line contact with
    1/Re = 1/R1 + 1/R2 on the convex cylinder, 1/R1 - 1/R2 in the concave seat."""
    import json
    import re

    from test_gmsh_examples import EX, NU, E, F, _measure
    R1, R2 = 20.0, 60.0
    Re = 1.0 / (1.0 / R1 + (1.0 if side == "outside" else -1.0) / R2)
    Es = E / (1 - NU ** 2)
    a_ex = math.sqrt(4 * F * Re / (math.pi * Es))
    p_ex = 2 * F / (math.pi * a_ex)
    (tmp_path / "half_disk.geo").write_text((EX / "half_disk.geo").read_text())
    centre = [0.0, -R2] if side == "outside" else [0.0, R2]
    text = re.sub(r"^outputs:.*$", "", (EX / "half_disk.yaml").read_text(), flags=re.M)
    text = text.replace("obstacle: {point: [0, 0], normal: [0, -1]}",
                        f"obstacle: {{type: circle, centre: {centre}, radius: {R2}, side: {side}}}")
    assert "type: circle" in text
    (tmp_path / "s.yaml").write_text(text)
    p = run_cli_here("run", str(tmp_path / "s.yaml"), "-o", str(tmp_path / "out"), "-q")
    assert p.returncode == 0, p.stderr
    res = json.loads((tmp_path / "out" / "results.json").read_text())
    assert res["states"][-1]["load"]["normal_resultant"] == pytest.approx(F, rel=1e-10)
    assert all(st["contact_solve"]["violation"] <= 1e-9 for st in res["states"])
    a, p0, x, _ = _measure(res)
    print(f"{side}: Re = {Re:.4g} mm, a = {a:.4f} (Hertz {a_ex:.4f}), p0 = {p0:.4f} (Hertz {p_ex:.4f})")
    assert abs(a / a_ex - 1) <= 0.75 * 0.04 / a_ex + 0.005          # edge resolution: half a cell
    assert abs(p0 / p_ex - 1) <= 0.02


@pytest.fixture(scope="module")
def shipped_curved(tmp_path_factory):
    """The shipped half-disk examples on the convex cylinder and in the concave seat, as shipped
    (mu_cap 100, certified) but MCEIP-mu only and without pictures: name -> (folder, results)."""
    import json

    from test_gmsh_examples import EX
    d = tmp_path_factory.mktemp("shipped_curved")
    (d / "half_disk_curved.geo").write_text((EX / "half_disk_curved.geo").read_text())
    out = {}
    for name in ("half_disk_cylinder", "half_disk_seat"):
        text = re.sub(r"^outputs:.*$", "", (EX / f"{name}.yaml").read_text(), flags=re.M)
        text = re.sub(r"^analyses:.*$", "analyses: [mceip_mu]", text, flags=re.M)
        assert "mu_cap: 100" in text
        (d / f"{name}.yaml").write_text(text)
        p = run_cli_here("run", str(d / f"{name}.yaml"), "-o", str(d / name), "-q")
        assert p.returncode == 0, p.stderr
        out[name] = (d / name, json.loads((d / name / "results.json").read_text()))
    return out


def test_convex_and_concave_examples(shipped_curved):
    """The shipped half-disk examples (README "Curved obstacles"): gross sliding where the
    tangential resultant is mu times the normal one; on the convex cylinder critical friction
    coefficients at every state once a node slips in the shear, in the concave seat none below
    the cap (100) from state 10 on, proven."""
    out = {name: res for name, (_, res) in shipped_curved.items()}
    for res in out.values():
        assert "gross sliding" in res["path"]["end"] and res["failures"] == []
        last = res["states"][-1]["load"]
        assert last["tangential_resultant"] == pytest.approx(1.1 * last["normal_resultant"], rel=1e-8)
    cyl, seat = out["half_disk_cylinder"]["states"], out["half_disk_seat"]["states"]
    assert all(mu_values(s) for s in cyl if s["load"]["name"] == "shear" and s["classification"]["slip"] > 0)
    for s in seat[10:]:
        m = s["analyses"]["mceip_mu"]
        assert not [v for v in mu_values(s) if v <= 100.0]
        assert m["complete"]["proven"] and m["complete"]["count"] == 0, (s["index"], m["result"])
    print("smallest critical mu: cylinder", min(min(mu_values(s)) for s in cyl if mu_values(s)),
          "seat", min(min(mu_values(s)) for s in seat if mu_values(s)))


@pytest.mark.slow
def test_curved_examples_proven_beyond_ten_slip_nodes(shipped_curved):
    """The half-disk examples with their proofs (mu_cap 100): every state with 11 to 16 slip nodes
    is proven by the branch and bound (onset and complete list), its proven list is the
    floating-point enumeration's where s <= 14, and `app check` re-verifies every stored log."""
    import json

    from conftest import run_cli

    from app.analyses.mceip_mu.quadratic.problem import enumerate_quadratic
    for name, (folder, res) in shipped_curved.items():
        big = [s for s in res["states"] if s["classification"]["slip"] > 10]
        assert big
        for s in big:
            m = s["analyses"]["mceip_mu"]
            assert m["certified"] and m["onset"]["proven"] and m["complete"]["proven"], (s["index"], m["result"])
        for f in (folder / "proofs").glob("state_*.npz"):
            with np.load(f) as z:
                A0, A1, A2, log = z["A0"], z["A1"], z["A2"], json.loads(str(z["log"]))
            if not 10 < A0.shape[0] <= 14:
                continue
            assert log["format"] == "mceip-mu-quadratic-bb/1"
            st = next(s for s in res["states"] if s["index"] == int(f.stem.split("_")[1]))
            proven = [x["value"] for x in st["analyses"]["mceip_mu"]["solutions"] if x["value"] <= 100]
            found = [x["value"] for x in enumerate_quadratic(A0, A1, A2, 14) if x["value"] <= 100]
            assert proven == pytest.approx(found, rel=1e-9)
        p = run_cli("check", str(folder))
        assert p.returncode == 0 and "claims re-verified from the stored pencils" in p.stdout, p.stdout + p.stderr

