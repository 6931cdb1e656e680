"""Field outputs (ParaView files, fields.npz for the screenshots) of any body, through the system's
field capability (app/systems/base.py ``FieldSource``; app/io/fields.py):

* the gmsh paper block writes the built-in block's fields (P1 on the paper mesh, P2 on a coarse one);
* the rotated block on an inclined obstacle writes the rotated fields: displacements and modes
  rotated, von Mises unchanged, slip directions and reactions along the incline's tangent/normal;
  condensed and full-size MCEIP-mu modes agree in the node frames;
* a P2 body writes a readable XDMF (quadratic cells with their mid-side nodes);
* 1 and 2 MPI ranks write the same fields.npz;
* a matrices system skips field outputs that only defaults turned on, and refuses them when asked.
"""
import json
import math
import pathlib

import numpy as np
import pytest
from conftest import ROOT, run_cli
from mpi4py import MPI
from test_gmsh_body import gmsh_scene, write_block_msh

GEO = ROOT / "app" / "scenes" / "gmsh" / "block.geo"
DRAG_STEPS, DRAG = 20, 2.0          # CD dragged 2 mm in 0.1 mm steps (past the first slip, before gross sliding)
FIELD_OUTPUTS = {"paraview": True, "states": ["final", "first_mceip_mu"],
                 "screenshots": {"resolution": [320, 200]}}


def _block(nx, ny, pattern, degree=1, **settings):
    return {"name": "b", "system": {"type": "block", "nx": nx, "ny": ny, "pattern": pattern, "degree": degree},
            "mu": 1.1, "analyses": ["mceip_mu"], "loading": {"tangential_step": DRAG / DRAG_STEPS, "tangential_max": DRAG},
            "outputs": FIELD_OUTPUTS, **({"settings": settings} if settings else {})}


def _gmsh(file, angle_deg=0.0, point=(0.0, 0.0), degree=1, **settings):
    s = gmsh_scene(file, angle_deg=angle_deg, point=point, degree=degree)
    c, si = math.cos(math.radians(angle_deg)), math.sin(math.radians(angle_deg))
    s["system"]["program"][1].update(steps=DRAG_STEPS, displacement={"CD": {"translation": [-DRAG * c, -DRAG * si]}})
    s["outputs"] = FIELD_OUTPUTS
    if settings:
        s["settings"] = settings
    return s


def _run(data: dict, out: pathlib.Path) -> tuple[dict, dict]:
    """Run a scene in this process with its field stage writing into ``out``; (results, fields.npz)."""
    from app.scene.schema import parse_scene
    from app.study.run import study
    out.mkdir(parents=True, exist_ok=True)
    res = study(parse_scene(data), MPI.COMM_WORLD, outdir=out).to_dict()
    with np.load(out / "fields" / "fields.npz") as z:
        fields = {k: z[k].copy() for k in z.files}
    return res, fields


def _series(path: pathlib.Path):
    import meshio
    with meshio.xdmf.TimeSeriesReader(str(path)) as r:
        points, cells = r.read_points_cells()
        steps = [r.read_data(k) for k in range(r.num_steps)]
    return points, cells, steps


def _rel(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.abs(a - b).max() / max(np.abs(a).max(), 1e-300))


def assert_same_fields(f1: dict, f2: dict, tol: float = 1e-8) -> None:
    """Same mesh (canonical order), contact nodes, pictured states and modes; fields to ``tol`` of their scale."""
    assert np.allclose(f1["points"], f2["points"], rtol=0, atol=1e-12 * np.abs(f1["points"]).max())
    assert np.array_equal(f1["cells"], f2["cells"]) and str(f1["cell_type"]) == str(f2["cell_type"])
    assert np.array_equal(f1["contact_points"], f2["contact_points"])
    assert np.array_equal(f1["state_index"], f2["state_index"]) and len(f1["state_index"]) >= 2
    m1, m2 = json.loads(str(f1["modes_json"])), json.loads(str(f2["modes_json"]))
    assert [m["name"] for m in m1] == [m["name"] for m in m2] and len(m1) >= 1
    for k in ("state_u", "state_von_mises", "mode_v"):
        assert f1[k].shape == f2[k].shape
        for a, b in zip(f1[k], f2[k]):
            assert _rel(a, b) < tol, k


def test_gmsh_paper_block_writes_the_built_in_blocks_fields(tmp_path):
    """The paper mesh (20 x 10 crossed) as a .msh: same displacement, stress, mode and contact fields."""
    ref, f_ref = _run(_block(20, 10, "crossed"), tmp_path / "block")
    got, f_got = _run(_gmsh(write_block_msh(tmp_path / "paper.msh", 20, 10, "crossed")), tmp_path / "gmsh")
    assert ref["outputs"]["contact_displacement_check"] < 1e-10 and got["outputs"]["contact_displacement_check"] < 1e-10
    assert [n["status"] for n in ref["states"][-1]["nodes"]] == [n["status"] for n in got["states"][-1]["nodes"]]
    assert any(n["status"] == "slip" for n in got["states"][-1]["nodes"])
    assert_same_fields(f_ref, f_got)
    (_, _, sa), (_, _, sb) = _series(tmp_path / "block" / "paraview" / "states.xdmf"), \
        _series(tmp_path / "gmsh" / "paraview" / "states.xdmf")
    assert len(sa) == len(sb) == len(ref["states"])
    for (_, da, ca), (_, db, cb) in zip(sa, sb):
        assert np.array_equal(da["contact_status"], db["contact_status"])
        assert np.array_equal(da["slip_direction"], db["slip_direction"])
        for k in ("displacement", "reaction"):
            assert np.allclose(da[k], db[k], rtol=0, atol=1e-8 * max(np.abs(da[k]).max(), 1e-300)), k


def test_inclined_block_writes_the_rotated_fields(tmp_path):
    """The block (10 x 5) rotated by 30 degrees about A and shifted, on the obstacle rotated with it:
    every vector field is the block's rotated, von Mises unchanged; slip directions are unit
    tangents of the incline; condensed and full-size MCEIP-mu modes agree in the node frames."""
    from scipy.spatial import cKDTree
    angle, shift = 30.0, np.array([3.0, -2.0])
    c, s = math.cos(math.radians(angle)), math.sin(math.radians(angle))
    Q = np.array([[c, -s], [s, c]])
    t, n = Q @ [1.0, 0.0], Q @ [0.0, -1.0]          # the incline's tangent and the body's outward normal
    ref, f_ref = _run(_block(10, 5, "crossed"), tmp_path / "block")
    msh = write_block_msh(tmp_path / "rot.msh", 10, 5, "crossed", angle, tuple(shift))
    got, f_got = _run(_gmsh(msh, angle_deg=angle, point=shift), tmp_path / "rot")
    full, f_full = _run(_gmsh(msh, angle_deg=angle, point=shift, mceip_mu_method="full"), tmp_path / "full")
    assert got["outputs"]["contact_displacement_check"] < 1e-10
    # node j of the rotated mesh is node perm[j] of the block's
    dist, perm = cKDTree(f_ref["points"] @ Q.T + shift).query(f_got["points"])
    assert dist.max() < 1e-9 * 80
    assert np.array_equal(perm[f_got["contact_points"]], f_ref["contact_points"])
    assert np.array_equal(f_got["state_index"], f_ref["state_index"])
    for k in ("state_u", "mode_v"):
        for a, b in zip(f_ref[k], f_got[k]):
            assert _rel(a[perm] @ Q.T, b) < 1e-8, k
    for a, b in zip(f_ref["state_von_mises"], f_got["state_von_mises"]):
        assert np.allclose(np.sort(a), np.sort(b), rtol=0, atol=1e-8 * a.max())
    assert np.allclose(f_got["contact_tangent"], t) and np.allclose(f_got["contact_normal"], n)
    assert np.allclose(f_got["obstacle_point"], shift) and np.allclose(f_got["obstacle_normal"], n)
    # ParaView: slip directions are unit tangents of the incline; reactions r_T t + r_N n
    _, _, steps = _series(tmp_path / "rot" / "paraview" / "states.xdmf")
    _, _, ref_steps = _series(tmp_path / "block" / "paraview" / "states.xdmf")
    nslip = 0
    for st, (_, d, _), (_, dr, _) in zip(got["states"], steps, ref_steps):
        cp = f_got["contact_points"]
        for node, j in zip(st["nodes"], cp):
            sd, r = d["slip_direction"][j, :2], d["reaction"][j, :2]
            assert np.allclose(r, node["r_T"] * t + node["r_N"] * n, rtol=0, atol=1e-12 * (1 + np.abs(r).max()))
            if node["status"] == "slip":
                nslip += 1
                assert abs(sd @ n) < 1e-12 and abs(np.linalg.norm(sd) - 1) < 1e-12
                assert sd @ t == pytest.approx(-node["sign"])
            else:
                assert not sd.any()
        assert np.allclose(d["slip_direction"][:, :2], dr["slip_direction"][perm, :2] @ Q.T, atol=1e-12)
        assert np.allclose(d["reaction"][:, :2], dr["reaction"][perm, :2] @ Q.T, rtol=0,
                           atol=1e-8 * max(np.abs(dr["reaction"]).max(), 1e-300))
    assert nslip > 0
    # exact (full-size) and condensed modes, both mapped back through the node frames
    # (the full-size search and the condensed one need not find the same solutions: compare the common ones)
    mf, mc = json.loads(str(f_full["modes_json"])), json.loads(str(f_got["modes_json"]))
    assert all(m["built"].startswith("exact") for m in mf) and all(m["built"].startswith("static") for m in mc)
    names_c = [m["name"] for m in mc]
    common = [(i, names_c.index(m["name"])) for i, m in enumerate(mf) if m["name"] in names_c]
    assert common
    for i, j in common:
        assert np.abs(f_full["mode_v"][i] - f_got["mode_v"][j]).max() < 1e-8


def test_p2_body_writes_a_readable_xdmf_equal_to_the_built_in_block(tmp_path):
    """P2 on a coarse block (8 x 4, the .geo's pattern 'right'): quadratic cells in VTK order (mid-side
    nodes at the edge midpoints), the built-in P2 block's fields, contact displacements of the results."""
    geo = tmp_path / "block.geo"
    geo.write_text(GEO.read_text().replace("nx = 20; ny = 10;", "nx = 8; ny = 4;"))
    ref, f_ref = _run(_block(8, 4, "right", degree=2), tmp_path / "block")
    got, f_got = _run(_gmsh(geo, degree=2), tmp_path / "gmsh")
    assert_same_fields(f_ref, f_got)
    points, cells, steps = _series(tmp_path / "gmsh" / "paraview" / "states.xdmf")
    assert [b.type for b in cells] == ["triangle6"] and len(points) == 17 * 9
    tri = cells[0].data
    assert tri.shape == (64, 6) and len(np.unique(tri)) == len(points)
    for a, b, m in ((0, 1, 3), (1, 2, 4), (2, 0, 5)):
        assert np.allclose(points[tri[:, m]], 0.5 * (points[tri[:, a]] + points[tri[:, b]]), atol=1e-12)
    assert len(steps) == len(got["states"])
    for st, (_, d, cd) in zip(got["states"], steps):
        assert cd["von_mises"][0].shape == (64,) and np.all(np.isfinite(cd["von_mises"][0]))
        u = d["displacement"][f_got["contact_points"], :2]
        want = np.array([[nd["u_T"], -nd["u_N"]] for nd in st["nodes"]])    # T = +x, N = -y
        assert np.allclose(u, want, rtol=0, atol=1e-9 * max(np.abs(d["displacement"]).max(), 1e-300))


@pytest.mark.mpi
def test_fields_same_on_two_ranks(tmp_path):
    """The inclined block (10 x 5, 30 degrees): fields.npz of 1 and 2 ranks agree."""
    import yaml
    msh = write_block_msh(tmp_path / "rot.msh", 10, 5, "crossed", 30.0, (3.0, -2.0))
    data = _gmsh(msh, angle_deg=30.0, point=(3.0, -2.0))
    data["outputs"] = {**FIELD_OUTPUTS, "paraview": False}
    _, f1 = _run(data, tmp_path / "o1")
    (tmp_path / "s.yaml").write_text(yaml.safe_dump(data))
    p = run_cli("run", str(tmp_path / "s.yaml"), "-o", str(tmp_path / "o2"), "-q", ranks=2)
    assert p.returncode == 0, p.stderr
    assert json.loads((tmp_path / "o2" / "results.json").read_text())["mpi_ranks"] == 2
    with np.load(tmp_path / "o2" / "fields" / "fields.npz") as z:
        f2 = {k: z[k].copy() for k in z.files}
    assert sorted(f1) == sorted(f2)
    assert_same_fields(f1, f2)
    assert len(list((tmp_path / "o2" / "screenshots").glob("*.png"))) >= 2


def test_matrices_skip_default_field_outputs_and_refuse_asked_ones(tmp_path):
    """No mesh: ParaView files and screenshots switched on only by defaults are skipped with one note
    (plots and report drawn); written in the scene they are a one-line error."""
    from test_matrices import particle_scene

    from app.plot.pictures import draw_after_run
    from app.scene.schema import SceneError, parse_scene
    from app.scene.sections import Outputs, Screenshots
    from app.study.run import study
    data = particle_scene(tmp_path, (1, -1), 2.5, analyses=("necessary", "mceip_mu"))
    for key, value in (("paraview", True), ("screenshots", {})):
        with pytest.raises(SceneError, match=f"outputs.{key} = True: needs a mesh: not applicable, a matrices "
                                             "system has no mesh") as err:
            parse_scene({**data, "outputs": {key: value}})
        assert "\n" not in str(err.value)
    scene = parse_scene({**data, "outputs": {"plots": True, "report": True}})
    # defaults that turn the field outputs on: not in the scene's fields_set
    outputs = Outputs.model_construct(_fields_set={"plots", "report"}, paraview=True, plots=True, report=True,
                                      states=["final"], screenshots=Screenshots())
    scene = scene.model_copy(update={"outputs": outputs})
    type(scene.system).check_scene(scene)                      # not refused
    out = tmp_path / "out"
    out.mkdir()
    res = study(scene, MPI.COMM_WORLD, outdir=out)
    why = "ParaView files and screenshots not applicable: a matrices system has no mesh"
    assert res.outputs.notes == [why] and res.outputs.files == []
    res = draw_after_run(res, out)
    assert not (out / "paraview").exists() and not (out / "screenshots").exists() and not (out / "fields").exists()
    assert (out / "plots" / "status_map.png").stat().st_size > 1000 and (out / "plots" / "reactions.png").exists()
    assert res.outputs.notes.count(why) == 1 and not any("screenshots" in n and n != why for n in res.outputs.notes)
    assert why in (out / "report.md").read_text()


LAYERED = """// two layers: soft bottom (y < 10), stiff top; 40 x 20 mm
h = 2.5;
Point(1) = {0, 0, 0, h}; Point(2) = {40, 0, 0, h}; Point(3) = {40, 10, 0, h}; Point(4) = {0, 10, 0, h};
Point(5) = {40, 20, 0, h}; Point(6) = {0, 20, 0, h};
Line(1) = {1, 2}; Line(2) = {2, 3}; Line(3) = {3, 4}; Line(4) = {4, 1};
Line(5) = {3, 5}; Line(6) = {5, 6}; Line(7) = {6, 4};
Curve Loop(1) = {1, 2, 3, 4}; Plane Surface(1) = {1};
Curve Loop(2) = {-3, 5, 6, 7}; Plane Surface(2) = {2};
Physical Curve("bottom") = {1}; Physical Curve("top") = {6}; Physical Curve("sides") = {2, 4, 5, 7};
Physical Surface("soft") = {1}; Physical Surface("stiff") = {2};
"""


def test_layered_body_loaded_every_way_writes_consistent_fields(tmp_path):
    """Two materials, CD pressed then rotated about a point, a traction on the sides and gravity:
    the field reproduces the contact displacements, the top curve moves rigidly as prescribed, and
    the von Mises stress equals the one computed independently from the nodal field (constant
    strain per P1 triangle, each layer's E and nu, plane stress)."""
    (tmp_path / "layers.geo").write_text(LAYERED)
    mats = {"soft": {"E": 5.0, "nu": 0.45}, "stiff": {"E": 50.0, "nu": 0.3}}
    data = {"name": "layers", "mu": 0.8, "analyses": ["mceip_mu"],
            "system": {"type": "gmsh", "file": str(tmp_path / "layers.geo"), "contact": "bottom",
                       "prescribed": {"top": "xy"}, "materials": mats, "thickness": 5.0,
                       "program": [{"name": "press", "steps": 2, "displacement": {"top": {"translation": [0, -1]}},
                                    "until": {"normal_force": 20.0}},
                                   {"name": "tilt", "steps": 3, "displacement": {"top": {"rotation_deg": 1.0,
                                                                                         "about": [20.0, 20.0]}},
                                    "traction": {"sides": [0.02, 0.0]}, "gravity": [0.0, -9810.0]}]},
            "outputs": {"paraview": True, "states": [2, "final"], "screenshots": True}}
    res, f = _run(data, tmp_path / "out")
    assert res["outputs"]["contact_displacement_check"] < 1e-10
    pts, cells = f["points"], f["cells"]
    top = np.flatnonzero(np.abs(pts[:, 1] - 20.0) < 1e-9)
    by_index = {s["index"]: s for s in res["states"]}
    for k, i in enumerate(f["state_index"]):
        par = by_index[int(i)]["load"]["parameters"]
        th = par.get("motion.top.rz", 0.0)
        want = np.column_stack([par.get("motion.top.tx", 0.0) - th * pts[top, 1],
                                par.get("motion.top.ty", 0.0) + th * pts[top, 0]])
        u = f["state_u"][k]
        assert np.allclose(u[top], want, rtol=0, atol=1e-12 * np.abs(u).max())
        if int(i) == res["states"][-1]["index"]:
            assert th != 0.0 and "gravity.y" in par and "traction.sides.x" in par
        # independent von Mises: constant strain of each P1 triangle
        x, uu = pts[cells], u[cells]                                   # (C, 3, 2)
        J = np.stack([x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]], axis=2)    # columns: edge vectors
        D = np.stack([uu[:, 1] - uu[:, 0], uu[:, 2] - uu[:, 0]], axis=2)
        G = D @ np.linalg.inv(J)                                       # displacement gradient
        eps = 0.5 * (G + np.transpose(G, (0, 2, 1)))
        soft = x[:, :, 1].mean(axis=1) < 10.0
        E = np.where(soft, 5.0, 50.0)
        nu = np.where(soft, 0.45, 0.3)
        c = E / (1 - nu ** 2)
        sxx = c * (eps[:, 0, 0] + nu * eps[:, 1, 1])
        syy = c * (eps[:, 1, 1] + nu * eps[:, 0, 0])
        sxy = E / (1 + nu) * eps[:, 0, 1]
        vm = np.sqrt(sxx ** 2 - sxx * syy + syy ** 2 + 3 * sxy ** 2)
        assert np.allclose(f["state_von_mises"][k], vm, rtol=1e-8, atol=1e-10 * vm.max())
