"""Outputs people look at: ParaView files, screenshots, plots, the report, ``render``, progress and logs.

One small block study with every output on is run once by the command line (serial) and once
under ``mpirun -n 2``; the tests check the files it leaves: every picture for its size and
non-blank content, the ParaView files (read back with meshio and pyvista) for their named fields,
sizes and values against results.json, the mode fields against the modes' definition, and the
parallel files against the serial ones. A scene without ``outputs`` must produce no pictures and
record no picture stage.
"""
from __future__ import annotations

import io
import json
import pathlib
import subprocess
import xml.etree.ElementTree as ET

import numpy as np
import pytest
import yaml
from conftest import PY, ROOT, minimal_study, run_cli, run_cli_here

SCENE = {
    "name": "outputs-test",
    "system": {"type": "block", "nx": 8, "ny": 4},
    "mu": 1.1,
    "mceip_lambda2_mu": 2.0,
    "loading": {"tangential_step": 0.2},
    "analyses": ["necessary", "mceip_mu", "mceip_lambda2"],
    "outputs": {"paraview": True, "plots": True, "report": True, "states": ["final", "first_mceip_mu"],
                "screenshots": {"resolution": [640, 400], "field": "von_mises"}},
}
PLOTS = ("status_map", "reactions", "mceip_mu", "necessary")
STATUS_CODE = {"free": 0, "zero": 1, "stick": 2, "slip": 3}


def _write_scene(d: pathlib.Path, data: dict, name: str = "scene.yaml") -> pathlib.Path:
    p = d / name
    p.write_text(yaml.safe_dump(data, sort_keys=False))
    return p


@pytest.fixture(scope="module")
def serial(tmp_path_factory):
    d = tmp_path_factory.mktemp("outputs")
    scene = _write_scene(d, SCENE)
    out = d / "out"
    p = run_cli("run", str(scene), "-o", str(out), "--log-level", "INFO")
    assert p.returncode == 0, p.stderr
    return out, json.loads((out / "results.json").read_text()), p


def _image(path: pathlib.Path) -> np.ndarray:
    from PIL import Image
    with Image.open(path) as im:
        return np.asarray(im.convert("RGB"), dtype=float)


def _assert_picture(path: pathlib.Path, size: tuple[int, int] | None = None, min_size=(300, 200),
                    drawn: float = 0.02) -> None:
    assert path.is_file() and path.stat().st_size > 5000, path
    img = _image(path)
    h, w, _ = img.shape
    if size is not None:
        assert (w, h) == tuple(size), (path, w, h)
    assert w >= min_size[0] and h >= min_size[1], (path, w, h)
    # not blank: pixel variance, and a fair share of pixels that are not the background
    assert img.std() > 20.0, (path, img.std())
    non_white = np.mean(np.any(img < 235, axis=2))
    assert non_white > drawn, (path, non_white)


def _states_series(path: pathlib.Path):
    import meshio
    with meshio.xdmf.TimeSeriesReader(str(path)) as r:
        points, cells = r.read_points_cells()
        steps = [r.read_data(k) for k in range(r.num_steps)]
    return points, cells, steps


def _mode_pictures(study, pictured: list[int]) -> set[str]:
    """The file names of the mode pictures of the states ``pictured`` of a typed study."""
    from app.io.select import analyses_of, modes_of
    want = set()
    for i in pictured:
        analyses, first = analyses_of(study.states, i)
        want |= {f"mode_s{first:04d}_{prob}_{k}_{sol.value:.6g}.png" for prob, k, sol in modes_of(analyses)}
    return want


def _all_modes(results: dict) -> list[tuple[int, str, int, object]]:
    """(state, problem, number, solution) of every mode of a results.json document's study."""
    from app.io.result import StudyResult
    from app.io.select import modes_of
    out = []
    for s in StudyResult.from_json(results).states:
        if s.analyses_shared_with is None:
            out += [(s.index, p, k, sol) for p, k, sol in modes_of(s.analyses)]
    return out


# -- the scene schema ---------------------------------------------------------------------------

def test_outputs_schema_defaults_off_and_clear_errors():
    from app.scene.schema import SceneError, parse_scene
    base = {"name": "x", "system": {"type": "block", "nx": 4, "ny": 2}, "mu": 1.0}
    o = parse_scene(base).outputs
    assert not (o.paraview or o.plots or o.report or o.screenshots) and not o.any
    o = parse_scene({**base, "outputs": {"screenshots": True, "states": [3, "final", {"stick": 2, "slip": 15}]}}).outputs
    assert o.screenshots.resolution == (1200, 800) and o.fields
    bad = [({"states": ["last"]}, "outputs.states.0 = 'last'"),
           ({"states": [{"stuck": 2}]}, "outputs.states.0.stuck"),
           ({"states": [True]}, "outputs.states.0 = True"),
           ({"screenshots": {"field": "pressure"}}, "outputs.screenshots.field"),
           ({"screenshots": {"resolution": [50, 50]}}, "outputs.screenshots.resolution.0 = 50"),
           ({"colour": "red"}, "unknown key 'outputs.colour'")]
    for outputs, needle in bad:
        with pytest.raises(SceneError) as err:
            parse_scene({**base, "outputs": outputs})
        assert needle in str(err.value) and "\n" not in str(err.value)
    with pytest.raises(SceneError, match="'first_mceip_mu' needs the analysis mceip_mu"):
        parse_scene({**base, "analyses": ["necessary"], "outputs": {"states": ["first_mceip_mu"]}})
    tp = {"name": "t", "system": {"type": "two_particles", "k": 1.0, "m": 1.0, "phi_deg": 30, "signs": [1, -1]},
          "mu": 1.0}
    assert parse_scene({**tp, "outputs": {"plots": True, "report": True}}).outputs.plots
    for key, value in (("paraview", True), ("screenshots", {})):
        with pytest.raises(SceneError, match=f"outputs.{key} = True: needs a mesh"):
            parse_scene({**tp, "outputs": {key: value}})


def test_state_selection():
    from app.io.select import select_states
    cls = lambda st, sl, fr: {"stick": st, "slip": sl, "free": fr, "zero": 0}   # noqa: E731
    states = minimal_study([
        {"index": 0, "classification": cls(5, 0, 0), "analyses_shared_with": None, "analyses": {}},
        {"index": 1, "classification": cls(5, 0, 0), "analyses_shared_with": 0, "analyses": {}},
        {"index": 2, "classification": cls(2, 2, 1), "analyses_shared_with": None,
         "analyses": {"mceip_mu": {"solutions": [{"value": 3.0}]}}},
        {"index": 3, "classification": cls(0, 4, 1), "analyses_shared_with": None,
         "analyses": {"mceip_mu": {"solutions": []}}}]).states
    assert select_states(states, ["final"]) == ([3], [])
    assert select_states(states, ["first_mceip_mu", 1]) == ([1, 2], [])
    assert select_states(states, ["all_distinct"]) == ([0, 2, 3], [])
    assert select_states(states, [{"stick": 2, "slip": 2}]) == ([2], [])
    chosen, notes = select_states(states, [{"stick": 9}, 17, "final"])
    assert chosen == [3] and len(notes) == 2 and "no such state" in notes[0]


# -- a study with every output ------------------------------------------------------------------

def test_every_picture_is_drawn_and_not_blank(serial):
    out, res, _ = serial
    for name in PLOTS:
        _assert_picture(out / "plots" / f"{name}.png", min_size=(800, 400))
        svg = ET.parse(out / "plots" / f"{name}.svg").getroot()
        assert svg.tag.endswith("svg") and len(list(svg.iter())) > 50
    shots = sorted((out / "screenshots").glob("*.png"))
    from app.io.result import StudyResult
    study = StudyResult.load(out)
    pictured = res["outputs"]["pictured_states"]
    first_mu = next(s["index"] for s in res["states"] if s["analyses"]["mceip_mu"]["solutions"])
    assert pictured == sorted({first_mu, res["states"][-1]["index"]})
    states = [p for p in shots if p.name.startswith("state_")]
    modes = [p for p in shots if p.name.startswith("mode_")]
    assert [p.name for p in states] == [f"state_{i:04d}_von_mises.png" for i in pictured]
    # a picture of every mode found at the pictured states (MCEIP-mu and MCEIP-lambda^2)
    assert {p.name for p in modes} == _mode_pictures(study, pictured)
    assert any("mceip_lambda2" in p.name for p in modes) and any("mceip_mu" in p.name for p in modes)
    for p in shots:
        _assert_picture(p, size=(640, 400), drawn=0.3)          # the block fills a good part of the picture


def test_report_ties_everything_together(serial):
    out, res, _ = serial
    text = (out / "report.md").read_text()
    for needle in ("# Study report: outputs-test", "## Distinct classifications", "| states |", "## Plots",
                   "## Screenshots", "## ParaView files", "## Scene", "## Versions", "fenics-dolfinx",
                   "pyvista", "## Stages", "screenshots (pyvista)"):
        assert needle in text, needle
    # every picture the report links exists, and every picture drawn is linked
    links = {line.split("](")[1].rstrip(")") for line in text.splitlines() if line.startswith("![")}
    drawn = {p.relative_to(out).as_posix() for p in out.glob("*/*.png")}
    assert links == drawn
    rows = [r for r in text.splitlines() if r.startswith("| ") and " / " in r and not r.startswith("| states")]
    assert len(rows) == res["distinct_classifications"]


def test_report_from_the_typed_study(serial, tmp_path):
    """``write_report`` takes the study's StudyResult (here read back from the run's results.json):
    every section, the notes, a link to each picture it is given, and one row per distinct
    classification with the study's own numbers."""
    from app.io.report import summary_table, write_report
    from app.io.result import StudyResult
    out, res, _ = serial
    study = StudyResult.load(out)
    pictured = study.outputs.pictured_states
    plots = [tmp_path / "plots" / f"{name}.png" for name in PLOTS]
    shots = [tmp_path / "screenshots" / f"state_{i:04d}_von_mises.png" for i in pictured]
    path = write_report(study, tmp_path, pictured, plots, shots, ["a note of the run"])
    assert path == tmp_path / "report.md"
    text = path.read_text()
    first = study.first_instability()
    c = first.classification
    for needle in ("# Study report: outputs-test", f"{study.system}; mu = 1.1; analyses: necessary, mceip_mu, "
                   "mceip_lambda2; MPI ranks: 1.", f"- {len(study)} equilibrium state(s), "
                   f"{study.distinct_classifications} distinct classification(s); the path ended: {study.path.end}.",
                   f"- MCEIP-mu first has a solution at state {first.index} ({c.stick} stick / {c.slip} slip / "
                   f"{c.free} free): mu = ", "Units: length mm, force N,", "## Distinct classifications",
                   "| states | CD u_x [mm] | stick / slip / free | min eig sym K* (19) | MCEIP-mu (pattern A to B) "
                   "| MCEIP-lambda^2 |", "## Plots", "## Screenshots", "Pictured states: final state, first state "
                   "with an MCEIP-mu solution -> states " + ", ".join(str(i) for i in pictured), "## ParaView files",
                   "## Notes\n\n- a note of the run\n", "## Stages", "| fields (ParaView files, screenshot data) |",
                   "## Scene", "## Versions", "fenics-dolfinx"):
        assert needle in text, needle
    links = {line.split("](")[1].rstrip(")") for line in text.splitlines() if line.startswith("![")}
    assert links == {p.relative_to(tmp_path).as_posix() for p in plots + shots}
    rows = summary_table(study)[2:]
    assert len(rows) == study.distinct_classifications and all(row in text for row in rows)
    for row, st in zip(rows, [s for s in study.states if s.analyses_shared_with is None]):
        cells = row.strip("| ").split(" | ")
        c = st.classification
        assert cells[0].split("-")[0] == str(st.index) and cells[2] == f"{c.stick} / {c.slip} / {c.free}"
        assert cells[3].startswith(f"{st.necessary.min_eig_K_sym:.4g}")
        assert cells[3].endswith(" (holds)") == bool(st.necessary.satisfied)
        for cell, analysis in ((cells[4], st.mceip_mu), (cells[5], st.mceip_lambda2)):
            assert all(f"{s.value:.6g} (" in cell for s in analysis.solutions)
            assert cell.startswith("none (") == (not analysis.solutions)


def test_report_cells_of_a_loading_program_and_of_failed_analyses(serial, tmp_path):
    """The report of a typed study whose states a loading program reached (phase name and step
    instead of CD u_x), with a failed analysis, analyses that have nothing to compute, failures
    and warnings."""
    from app.io.document import from_document
    from app.io.report import summary_table, write_report
    from app.io.result import StudyResult
    out, res, _ = serial
    data = from_document(json.loads((out / "results.json").read_text()))
    for st in data["states"]:     # phase "drag" is named in the scene, phase "press" is not
        st["load"] = {"phase": "press" if st["index"] < 3 else "drag", "step": st["index"],
                      "parameters": {"top_x": 0.1 * st["index"]}, **({"name": "drag it"} if st["index"] >= 3 else {})}
    shared = [s for s in data["states"] if s["analyses_shared_with"] is None]
    shared[1]["analyses"]["mceip_mu"] = {"failed": True, "reason": "no convergence"}
    shared[1]["analyses"]["necessary"] = {"failed": True, "reason": "no convergence"}
    shared[-1]["analyses"] = {"necessary": {"not_applicable": True, "reason": "no friction"},
                              "mceip_lambda2": {"not_applicable": True, "reason": "no friction"}}
    data["failures"] = [{"state": shared[1]["index"], "analysis": "mceip_mu", "reason": "no convergence"}]
    data["warnings"] = ["a warning of the run"]
    study = StudyResult.from_dict(data)
    rows = summary_table(study)
    assert rows[0].startswith("| states | load (phase step) | stick / slip / free |")
    cells = [r.strip("| ").split(" | ") for r in rows[2:]]
    ids = [s["index"] for s in shared]
    for cell, first in zip(cells, ids):
        members = [s.index for s in study.states if s.index == first or s.analyses_shared_with == first]
        label = [("drag it" if i >= 3 else "press") + f" {i}" for i in (members[0], members[-1])]
        assert cell[1] == (label[0] if len(members) == 1 else f"{label[0]} to {label[1]}")
    assert cells[1][3] == "failed" and cells[1][4] == "failed"
    assert cells[-1][3] == "n/a" and cells[-1][4] == "" and cells[-1][5] == "n/a"
    text = write_report(study, tmp_path, [], [], [], []).read_text()
    for needle in ("- stability analyses at the final state: no friction.",
                   f"- **incomplete**: 1 failure(s): state {ids[1]}: no convergence",
                   "- warning: a warning of the run"):
        assert needle in text, needle
    assert "- final state" not in text and "## Notes" not in text and "## Screenshots" not in text


def test_screenshots_from_the_typed_study_in_a_drawing_process(serial, tmp_path):
    """The screenshots of a StudyResult (read back from the run's results.json): drawn by a drawing
    process from the JSON job of ``job_of`` (as after a run), and by ``draw_screenshots`` in a
    process without DOLFINx (as ``render``), the same pictures, pixel for pixel."""
    from app.io.result import StudyResult
    from app.plot import worker
    from app.plot.screenshots import job_of, resolution_arg
    out, res, _ = serial
    study = StudyResult.load(out)
    cfg = study.scene_config["outputs"]["screenshots"]
    pictured = study.outputs.pictured_states
    fields = out / "fields" / "fields.npz"
    job = tmp_path / "job.json"
    job.write_text(json.dumps(job_of(study, pictured, cfg, tmp_path / "child", fields), allow_nan=False))
    files, notes, seconds = worker.Worker("screenshots", resolution_arg(cfg)).submit(job).wait()
    assert notes == [] and seconds is not None
    want = {f"state_{i:04d}_von_mises.png" for i in pictured} | _mode_pictures(study, pictured)
    assert sorted(p.name for p in files) == sorted(want) and all(p.parent == tmp_path / "child" for p in files)
    for p in files:
        _assert_picture(p, size=(640, 400), drawn=0.3)
    code = ("import json, pathlib, sys; from app.io.result import StudyResult; "
            "from app.plot.screenshots import draw_screenshots; "
            "study = StudyResult.load(sys.argv[1]); cfg = study.scene_config['outputs']['screenshots']; "
            "files, notes = draw_screenshots(study, study.outputs.pictured_states, cfg, pathlib.Path(sys.argv[2]), "
            "pathlib.Path(sys.argv[1]) / 'fields' / 'fields.npz'); "
            "assert 'dolfinx' not in sys.modules; print(json.dumps([[str(f) for f in files], notes]))")
    p = subprocess.run([PY, "-c", code, str(out), str(tmp_path / "here")], capture_output=True, text=True,
                       timeout=300, cwd=ROOT)
    assert p.returncode == 0, p.stderr
    here, notes = json.loads(p.stdout.splitlines()[-1])
    assert notes == [] and [pathlib.Path(f).name for f in here] == [f.name for f in files]
    for f in files:
        assert np.array_equal(_image(f), _image(tmp_path / "here" / f.name)), f.name


def test_recorded_stages_and_files(serial):
    out, res, proc = serial
    names = [s["name"] for s in res["stages"]]
    for stage in ("fields (ParaView files, screenshot data)", "plots (matplotlib)", "screenshots (pyvista)", "report"):
        assert stage in names
    assert set(res["outputs"]["files"]) >= {"paraview/states.xdmf", "paraview/states.h5", "paraview/modes.vtu",
                                            "fields/fields.npz", "report.md", "plots/status_map.png"}
    assert all((out / f).is_file() for f in res["outputs"]["files"])
    assert res["outputs"]["contact_displacement_check"] < 1e-10
    assert res["scene_config"]["outputs"]["paraview"] is True
    assert "outputs:" in proc.stdout and "report.md" in proc.stdout


def test_drawing_job_files_are_removed(serial):
    """The job files handed to the drawing processes (app/plot/pictures.py, worker.py) are
    removed before the results are committed: none is left in the results folder."""
    out, res, proc = serial
    assert sorted(p.name for p in out.rglob(".pictures-job*")) == []


def test_fields_file_of_the_previous_release_keeps_its_obstacle(serial, tmp_path):
    """``python -m app render`` of a results folder of the previous release: its fields.npz has the
    ``block`` key instead of the geometry keys; the obstacle is then the block's line y = 0."""
    from app.plot.canvas import FieldData
    out, res, proc = serial
    with np.load(out / "fields" / "fields.npz") as z:
        now = {k: z[k] for k in z.files}
    assert FieldData(out / "fields" / "fields.npz").obstacle is not None
    old = {k: v for k, v in now.items() if k not in ("contact_tangent", "contact_normal", "length_scale",
                                                     "obstacle_point", "obstacle_normal")}
    np.savez(tmp_path / "old.npz", **old, block=np.array([80.0, 40.0]))
    p, n = FieldData(tmp_path / "old.npz").obstacle
    assert np.allclose(p, 0.0) and np.allclose(n, [0.0, -1.0])
    np.savez(tmp_path / "none.npz", **old, length_scale=np.array(80.0))     # a body without an obstacle line
    assert FieldData(tmp_path / "none.npz").obstacle is None


def test_paraview_states_series(serial):
    out, res, _ = serial
    points, cells, steps = _states_series(out / "paraview" / "states.xdmf")
    n_pts, n_cells = len(points), len(cells[0].data)
    assert cells[0].type == "triangle" and n_cells == 4 * 8 * 4       # crossed: 4 triangles per cell
    assert n_pts == 9 * 5 + 8 * 4                                       # grid nodes + cell centres
    # ParaView's time is the load: the distance CD travelled, pressed then dragged
    from app.io.result import StudyResult
    from app.io.select import load_axis
    x, _, is_load = load_axis(StudyResult.from_json(res).states, {"length": "mm"})
    assert is_load and [t for t, _, _ in steps] == pytest.approx(list(x), rel=1e-15)
    for (t, pd, cd), st in zip(steps, res["states"]):
        assert pd["displacement"].shape == (n_pts, 3) and cd["von_mises"][0].shape == (n_cells,)
        assert pd["contact_status"].shape == (n_pts,)
        assert pd["reaction"].shape == (n_pts, 3) and pd["slip_direction"].shape == (n_pts, 3)
        on_ab = np.flatnonzero(pd["contact_status"] >= 0)
        on_ab = on_ab[np.argsort(points[on_ab, 0])]
        nodes = st["nodes"]
        assert len(on_ab) == len(nodes)
        assert np.allclose(points[on_ab, 0], [n["x"] for n in nodes]) and np.allclose(points[on_ab, 1], 0)
        assert list(pd["contact_status"][on_ab]) == [STATUS_CODE[n["status"]] for n in nodes]
        # paper axes T = +x, N = -y
        scale = max(1e-12, np.abs(pd["displacement"]).max())
        assert np.allclose(pd["displacement"][on_ab, 0], [n["u_T"] for n in nodes], atol=1e-9 * scale)
        assert np.allclose(pd["displacement"][on_ab, 1], [-n["u_N"] for n in nodes], atol=1e-9 * scale)
        assert np.allclose(pd["reaction"][on_ab, 0], [n["r_T"] for n in nodes])
        assert np.allclose(pd["reaction"][on_ab, 1], [-n["r_N"] for n in nodes])
        assert np.allclose(pd["slip_direction"][on_ab, 0],
                           [-n["sign"] if n["status"] == "slip" else 0 for n in nodes])
        assert np.all(cd["von_mises"][0] >= 0)
        if t > 0:
            assert cd["von_mises"][0].max() > 0
    # CD moves with the prescribed displacement of the last state
    last = res["states"][-1]["load"]
    top = np.flatnonzero(np.isclose(points[:, 1], 40.0))
    assert np.allclose(steps[-1][1]["displacement"][top, :2], [last["u_x"], last["u_y"]])
    # pyvista (VTK's XDMF reader, as ParaView) reads the same file with its time steps
    import pyvista as pv
    reader = pv.get_reader(str(out / "paraview" / "states.xdmf"))
    assert len(reader.time_values) == len(res["states"])
    reader.set_active_time_value(reader.time_values[-1])
    mesh = reader.read()
    block = next(b for b in mesh if b is not None and "displacement" in b.point_data)
    assert block.n_points == n_pts and block.n_cells == n_cells and "von_mises" in block.cell_data
    assert np.allclose(block.point_data["displacement"], steps[-1][1]["displacement"])


def test_paraview_modes_are_the_modes_found(serial):
    import meshio
    out, res, _ = serial
    vtu = meshio.read(out / "paraview" / "modes.vtu")
    modes = _all_modes(res)
    assert sorted(vtu.point_data) == sorted(f"s{f:04d}_{p}_{k}_{sol.value:.6g}" for f, p, k, sol in modes)
    assert len(modes) >= 3
    points = vtu.points
    by_index = {s["index"]: s for s in res["states"]}
    for first, problem, k, sol in modes:
        v = vtu.point_data[f"s{first:04d}_{problem}_{k}_{sol.value:.6g}"]
        assert v.shape == (len(points), 3)
        assert np.linalg.norm(v, axis=1).max() == pytest.approx(1.0)
        nodes = by_index[first]["nodes"]
        ab = [int(np.flatnonzero(np.isclose(points[:, 0], n["x"]) & np.isclose(points[:, 1], 0.0))[0]) for n in nodes]
        stick = [j for j, n in zip(ab, nodes) if n["status"] == "stick"]
        slip = [(j, n) for j, n in zip(ab, nodes) if n["status"] == "slip"]
        assert np.allclose(v[stick], 0.0, atol=1e-12)                     # stick nodes do not move
        assert np.allclose([v[j, 1] for j, _ in slip], 0.0, atol=1e-12)   # slip nodes stay on the obstacle
        # slip nodes move along -S x_Ts (one positive factor for all)
        vx = np.array([v[j, 0] for j, _ in slip])
        want = -np.array([n["sign"] for _, n in slip]) * np.array(sol.x_Ts)
        c = float(vx @ want / (want @ want))
        assert c > 0 and np.allclose(vx, c * want, atol=1e-10)
        # the whole block takes part: the interior moves
        assert np.linalg.norm(v[points[:, 1] > 0], axis=1).max() > 0.05
    built = {m["built"].split(":")[0] for m in res["outputs"]["modes"]}
    assert built == {"exact", "static response to the contact rates (W_cc r_c = v_c)"}


def test_render_redraws_without_recomputing(serial, tmp_path):
    import shutil
    out, res, _ = serial
    copy = tmp_path / "copy"
    shutil.copytree(out, copy)
    before = (copy / "results.json").read_bytes()
    pictures = sorted(p.relative_to(copy).as_posix() for p in copy.glob("*/*.png")) + ["report.md"]
    for p in pictures:
        (copy / p).unlink()
    code = ("import sys; from app.cli.main import main; rc = main(['render', sys.argv[1]]); "
            "assert 'dolfinx' not in sys.modules, 'render imported DOLFINx'; "
            "assert 'app.study.run' not in sys.modules; sys.exit(rc)")
    p = subprocess.run([PY, "-c", code, str(copy)], capture_output=True, text=True, timeout=300, cwd=ROOT)
    assert p.returncode == 0, p.stderr
    assert sorted(p.relative_to(copy).as_posix() for p in copy.glob("*/*.png")) + ["report.md"] == pictures
    for name in pictures:
        if name.endswith(".png"):
            _assert_picture(copy / name)
    assert (copy / "results.json").read_bytes() == before          # the run's record is left alone
    assert f"redrew {len(pictures) + len(PLOTS)} file(s)" in p.stdout  # PNG + SVG plots, screenshots, report
    # a folder that is not a results folder
    p = run_cli_here("render", str(tmp_path))
    assert p.returncode == 2 and "no results.json" in p.stderr


def test_progress_and_log_lines(serial):
    _, res, proc = serial
    err = proc.stderr
    assert "\r" not in err                                            # not a terminal: plain lines
    n = len(res["states"])
    assert f"analyses: {n}/{n} states (100%)" in err and "loading:" in err
    assert f"fields: {n}/{n} states (100%)" in err and "screenshots:" in err
    assert "INFO: fields:" in err and "INFO: plots (matplotlib):" in err
    assert "running build_ext" not in err                          # the JIT's setuptools chatter is kept out


def test_progress_bar_on_a_terminal_and_quiet():
    from types import SimpleNamespace

    from app.common.progress import Progress

    class Tty(io.StringIO):
        def isatty(self):
            return True

    tty = Tty()
    bar = Progress(enabled=True, comm=SimpleNamespace(rank=0), stream=tty).bar(10, "analyses")
    for _ in range(10):
        bar.update(1)
    bar.close()
    assert "analyses" in tty.getvalue() and "10/10" in tty.getvalue() and "\r" in tty.getvalue()
    plain = io.StringIO()
    bar = Progress(enabled=True, comm=SimpleNamespace(rank=0), stream=plain, interval=0.0).bar(3, "loading")
    for _ in range(3):
        bar.update(1)
    bar.close()
    assert plain.getvalue().splitlines()[-1].startswith("loading: 3/3 states (100%)")
    assert "\r" not in plain.getvalue()
    for comm, enabled in ((SimpleNamespace(rank=1), True), (SimpleNamespace(rank=0), False)):
        quiet = io.StringIO()
        bar = Progress(enabled=enabled, comm=comm, stream=quiet).bar(3, "x")
        bar.update(3)
        bar.close()
        assert quiet.getvalue() == ""


# -- no pictures unless asked -------------------------------------------------------------------

def test_a_scene_without_outputs_draws_nothing(tmp_path):
    data = {k: v for k, v in SCENE.items() if k != "outputs"}
    data["analyses"] = ["mceip_mu"]
    out = tmp_path / "out"
    p = run_cli_here("run", str(_write_scene(tmp_path, data)), "-o", str(out), "-q")
    assert p.returncode == 0, p.stderr
    # results and the MCEIP-mu proofs (data, re-checked by ``python -m app check``), no pictures
    assert sorted(f.name for f in out.iterdir()) == [".contact-divergence.json", "proofs", "results.json", "steps.csv"]
    res = json.loads((out / "results.json").read_text())
    names = {s["name"] for s in res["stages"]}
    assert not names & {"fields (ParaView files, screenshot data)", "plots (matplotlib)", "screenshots (pyvista)",
                        "report"}
    assert "outputs" not in res and p.stderr == ""
    # and render has nothing to draw
    p = run_cli_here("render", str(out))
    assert p.returncode == 0 and "nothing to draw" in p.stdout
    assert sorted(f.name for f in out.iterdir()) == [".contact-divergence.json", "proofs", "results.json", "steps.csv"]


def test_two_particles_plots_and_report(tmp_path):
    data = {"name": "tp", "system": {"type": "two_particles", "k": 1000.0, "m": 2.0, "phi_deg": 35.0,
                                     "signs": [1, -1]},
            "mu": 2.5, "analyses": ["necessary", "mceip_mu", "mceip_lambda2"],
            "outputs": {"plots": True, "report": True}}
    out = tmp_path / "out"
    p = run_cli_here("run", str(_write_scene(tmp_path, data)), "-o", str(out), "-q")
    assert p.returncode == 0, p.stderr
    for name in PLOTS:
        _assert_picture(out / "plots" / f"{name}.png", min_size=(800, 400))
    text = (out / "report.md").read_text()
    assert "MCEIP-mu" in text and "## ParaView files" not in text and "## Screenshots" not in text
    assert not (out / "paraview").exists() and not (out / "screenshots").exists()
    data["outputs"] = {"paraview": True}
    p = run_cli_here("run", str(_write_scene(tmp_path, data, "bad.yaml")), "-o", str(tmp_path / "bad"))
    assert p.returncode == 2 and "outputs.paraview = True: needs a mesh" in p.stderr


def test_condensed_and_full_mode_fields_agree(tmp_path):
    """The two mode reconstructions: from x_Ts through W (condensed MCEIP-mu) and from the full
    kept-space vector (MCEIP-mu solved full size, as MCEIP-lambda^2 and the sufficient condition)."""
    from mpi4py import MPI

    from app.scene.schema import parse_scene
    from app.study.run import study
    fields = {}
    for method in ("condensed", "full"):
        data = {**{k: v for k, v in SCENE.items() if k != "outputs"}, "analyses": ["mceip_mu"],
                "settings": {"mceip_mu_method": method},
                "outputs": {"screenshots": {"modes": True}, "states": ["all_distinct"]}}
        out = tmp_path / method
        out.mkdir()
        res = study(parse_scene(data), MPI.COMM_WORLD, outdir=out)
        # the full-size solve keeps its kept-space vectors in memory, never in results.json
        kept = [sol for s in res.states for sol in s.analyses.mceip_mu.solutions]
        assert all("x" not in sol.to_dict() for sol in kept)
        assert any(sol.x is not None for sol in kept) == (method == "full")
        with np.load(out / "fields" / "fields.npz") as z:
            fields[method] = (json.loads(str(z["modes_json"])), z["mode_v"].copy())
    (m1, v1), (m2, v2) = fields["condensed"], fields["full"]
    assert [m["name"] for m in m1] == [m["name"] for m in m2] and len(m1) >= 3
    assert all(m["built"].startswith("static") for m in m1) and all(m["built"].startswith("exact") for m in m2)
    assert np.abs(v1 - v2).max() < 1e-8


# -- parallel -----------------------------------------------------------------------------------

@pytest.mark.mpi
@pytest.mark.slow
def test_parallel_files_match_serial(serial, tmp_path):
    import meshio
    out1, res1, _ = serial
    out2 = tmp_path / "out2"
    p = run_cli("run", str(_write_scene(tmp_path, SCENE)), "-o", str(out2), "-q", ranks=2)
    assert p.returncode == 0, p.stderr
    res2 = json.loads((out2 / "results.json").read_text())
    assert res2["mpi_ranks"] == 2
    a, b = _states_series(out1 / "paraview" / "states.xdmf"), _states_series(out2 / "paraview" / "states.xdmf")
    assert np.allclose(a[0], b[0], rtol=0, atol=1e-12) and np.array_equal(a[1][0].data, b[1][0].data)
    assert len(a[2]) == len(b[2]) == len(res2["states"])
    for (ta, pa, ca), (tb, pb, cb) in zip(a[2], b[2]):
        # the time is the load CD reached, computed (the press's depth), so equal to rounding
        assert ta == pytest.approx(tb, rel=1e-12) and sorted(pa) == sorted(pb)
        for k in pa:
            assert np.allclose(pa[k], pb[k], rtol=1e-8, atol=1e-10 * max(1.0, np.abs(pa[k]).max())), k
        assert np.allclose(ca["von_mises"][0], cb["von_mises"][0], rtol=1e-8, atol=1e-12)
    m1, m2 = meshio.read(out1 / "paraview" / "modes.vtu"), meshio.read(out2 / "paraview" / "modes.vtu")
    assert sorted(m1.point_data) == sorted(m2.point_data)
    for k in m1.point_data:
        assert np.allclose(m1.point_data[k], m2.point_data[k], atol=1e-8), k
    # rank 0 drew every picture
    shots1 = sorted(p.name for p in (out1 / "screenshots").glob("*.png"))
    assert sorted(p.name for p in (out2 / "screenshots").glob("*.png")) == shots1
    for p in list((out2 / "screenshots").glob("*.png")) + list((out2 / "plots").glob("*.png")):
        _assert_picture(p)
    assert (out2 / "report.md").is_file() and "MPI ranks: 2" in (out2 / "report.md").read_text()
