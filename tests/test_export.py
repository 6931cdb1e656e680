"""``python -m app export RESULTS --matrices`` (issue 35): K, M, and for each distinct
classification K*(mu), M*(mu) and the condensed MCEIP-mu pencil with the stored answers. The
exported pencils, re-proved by ``app.mceip_mu``, give the answers results.json states (a round trip
through Matrix Market files); the folder is new, never a replaced one."""
import json

import numpy as np
import pytest
import scipy.io
import scipy.sparse
import yaml
from conftest import ROOT, run_cli_here

import app


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    d = tmp_path_factory.mktemp("export")
    s = yaml.safe_load((ROOT / "app/scenes/villechaise_block.yaml").read_text())
    s.update(analyses=["mceip_mu"], outputs={"plots": False, "report": False})
    s["system"].update(nx=12, ny=6)
    (d / "s.yaml").write_text(yaml.safe_dump(s))
    run = run_cli_here("run", str(d / "s.yaml"), "-o", str(d / "res"), "-q")
    assert run.returncode == 0, run.stderr
    p = run_cli_here("export", str(d / "res"), "--matrices")
    assert p.returncode == 0, p.stderr
    return d / "res", d / "res-export", p.stdout


def test_every_classification_is_exported(exported):
    res, out, stdout = exported
    results = json.loads((res / "results.json").read_text())
    index = json.loads((out / "index.json").read_text())
    firsts = [s["index"] for s in results["states"] if s["analyses_shared_with"] is None]
    assert [c["state"] for c in index["classifications"]] == firsts and index["mu"] == results["mu"]
    assert stdout.strip() == f"{out}: {len(list(out.rglob('*.*')))} files (K, M and {len(firsts)} classifications)"
    K, M = (scipy.io.mmread(out / f"{n}.mtx").tocsr() for n in ("K", "M"))
    assert K.shape == M.shape == (index["dofs"],) * 2
    assert abs(K - K.T).max() <= 1e-12 * abs(K).max() and abs(M - M.T).max() <= 1e-12 * abs(M).max()
    for c in index["classifications"]:
        sub = out / c["folder"]
        answers = json.loads((sub / "answers.json").read_text())
        state = next(s for s in results["states"] if s["index"] == c["state"])
        assert answers["classification"] == state["classification"] and answers["slip_nodes"] == c["slip_nodes"]
        assert answers["mceip_mu"] == state["analyses"]["mceip_mu"]               # the record as stored
        Ks = scipy.io.mmread(sub / "Kstar.mtx")
        assert Ks.shape[0] == Ks.shape[1] == scipy.io.mmread(sub / "Mstar.mtx").shape[0]
        assert (sub / "A0.mtx").exists() == (c["slip_nodes"] > 0)


def test_the_exported_pencils_prove_the_stored_answers(exported):
    _, out, _ = exported
    index = json.loads((out / "index.json").read_text())
    proven = 0
    for c in index["classifications"]:
        if not c["slip_nodes"]:
            continue
        sub = out / c["folder"]
        stored = json.loads((sub / "answers.json").read_text())["mceip_mu"]
        A0, A1 = (np.asarray(scipy.io.mmread(sub / f"{n}.mtx")) for n in ("A0", "A1"))
        assert A0.shape == A1.shape == (c["slip_nodes"],) * 2
        cap = stored["certificate"]["cap"]
        r = app.mceip_mu(A0, A1, cap)
        assert r.onset.proven == stored["onset"]["proven"]
        if stored["onset"]["proven"] and stored["onset"]["value"] is not None:
            lo, hi = stored["onset"]["enclosure"]
            assert lo <= r.onset.value <= hi
            proven += 1
        if stored["complete"]["proven"]:
            assert r.all.proven
            assert [s.value for s in r.solutions if s.value <= cap] == pytest.approx(
                [s["value"] for s in stored["solutions"] if s["value"] <= cap], rel=1e-8)
    assert proven >= 3


def test_an_existing_folder_is_never_replaced(exported, tmp_path):
    res, out, _ = exported
    before = sorted(p.name for p in out.iterdir())
    p = run_cli_here("export", str(res), "--matrices", "-o", str(out))
    assert p.returncode == 2 and p.stderr == f"error: {out} exists: give a new folder with -o (an existing one is " \
                                             "never replaced)\n"
    assert sorted(p.name for p in out.iterdir()) == before
    missing = run_cli_here("export", str(tmp_path / "nothing"), "--matrices")
    assert missing.returncode == 2 and len(missing.stderr.splitlines()) == 1 and "not a folder" in missing.stderr
    empty = tmp_path / "empty"
    empty.mkdir()
    none = run_cli_here("export", str(empty), "--matrices", "-o", str(tmp_path / "x"))
    assert none.returncode == 2 and len(none.stderr.splitlines()) == 1 and "results.json" in none.stderr
    assert not (tmp_path / "x").exists() and not any(p.name.startswith(".x.partial") for p in tmp_path.iterdir())


@pytest.mark.parametrize("scene", sorted(p.relative_to(ROOT / "app/scenes").as_posix()
                                         for p in (ROOT / "app/scenes").rglob("*.yaml")))
def test_a_stored_scene_validates_again(scene):
    """results.json ``scene_config`` (the validated scene with every default) is a scene again:
    export rebuilds the system from it. A key given with its default value is no conflict (the
    obstacles' line keys beside a circle or a curve)."""
    from app.scene.schema import load_scene, parse_scene
    path = ROOT / "app/scenes" / scene
    first = load_scene(path)
    stored = first.model_dump(mode="json", exclude_none=True)        # as app/study/run.py stores it
    again = parse_scene(stored, "stored", path.parent)
    assert again.model_dump(mode="json", exclude_none=True) == stored


def test_a_curved_obstacle_exports_its_quadratic_pencil(tmp_path):
    s = yaml.safe_load((ROOT / "app/scenes/gmsh/half_disk_cylinder.yaml").read_text())
    s.update(analyses=["mceip_mu"])
    s.pop("outputs", None)
    s["system"]["file"] = str(ROOT / "app/scenes/gmsh" / s["system"]["file"])
    (tmp_path / "s.yaml").write_text(yaml.safe_dump(s))
    assert run_cli_here("run", str(tmp_path / "s.yaml"), "-o", str(tmp_path / "res"), "-q").returncode == 0
    # a Gmsh body names its .geo: the user gives the scene (a stored path is never opened)
    p = run_cli_here("export", str(tmp_path / "res"), "--matrices", "-o", str(tmp_path / "out"),
                     "--scene", str(tmp_path / "s.yaml"))
    assert p.returncode == 0, p.stderr
    index = json.loads((tmp_path / "out" / "index.json").read_text())
    slipping = [c for c in index["classifications"] if c["slip_nodes"]]
    assert slipping
    for c in slipping:
        sub = tmp_path / "out" / c["folder"]
        assert json.loads((sub / "answers.json").read_text())["quadratic"] is True
        assert all(np.asarray(scipy.io.mmread(sub / f"A{k}.mtx")).shape == (c["slip_nodes"],) * 2 for k in range(3))


def test_a_results_folder_from_someone_else_is_data(exported, tmp_path):
    """export reads results.json as ``check`` does (no symlink followed) and never opens a path
    the stored scene names (a Gmsh body's file: the user gives the scene with --scene, of the
    same system); a hostile folder is one line, and nothing is written."""
    import shutil
    res, _, _ = exported
    linked = tmp_path / "linked"
    linked.mkdir()
    (linked / "results.json").symlink_to(res / "results.json")
    p = run_cli_here("export", str(linked), "--matrices", "-o", str(tmp_path / "a"))
    assert p.returncode == 2 and len(p.stderr.splitlines()) == 1 and not (tmp_path / "a").exists()
    forged = tmp_path / "forged"
    shutil.copytree(res, forged)
    doc = json.loads((forged / "results.json").read_text())
    doc["scene_config"]["system"] = {"type": "gmsh", "file": "/etc/passwd", "contact": "bottom",
                                     "prescribed": {"top": "xy"}, "material": {"E": 5.0, "nu": 0.3},
                                     "program": [{"steps": 1, "displacement": {"top": {"translation": [0, -0.1]}}}]}
    (forged / "results.json").write_text(json.dumps(doc))
    p = run_cli_here("export", str(forged), "--matrices", "-o", str(tmp_path / "b"))
    assert p.returncode == 2 and len(p.stderr.splitlines()) == 1, p.stderr
    assert "the scene results.json stores cannot be rebuilt" in p.stderr and "a path read from there is never " \
        "opened: give the scene file yourself (export --scene)" in p.stderr and "root:" not in p.stderr
    assert not (tmp_path / "b").exists() and not any(".partial" in q.name for q in tmp_path.iterdir())
    other = run_cli_here("export", str(res), "--matrices", "-o", str(tmp_path / "c"),
                         "--scene", str(ROOT / "app/scenes/gmsh/l_shape.yaml"))
    assert other.returncode == 2 and "system.type = 'gmsh', but the results are of a 'block' system" in other.stderr
    assert not (tmp_path / "c").exists()


def test_chosen_states_and_pencils_only(exported, tmp_path):
    """``--states final --states first_mceip_mu --pencils-only``: the two classifications only (the
    first state of each), their condensed pencils and answers, none of the system-sized matrices;
    the same pencils as the full export's. A selector naming no state is one line."""
    res, full, _ = exported
    out = tmp_path / "few"
    p = run_cli_here("export", str(res), "--matrices", "-o", str(out), "--states", "final",
                     "--states", "first_mceip_mu", "--pencils-only")
    assert p.returncode == 0, p.stderr
    results = json.loads((res / "results.json").read_text())
    states = {s["index"]: s for s in results["states"]}

    def first_of(i):
        return states[i]["analyses_shared_with"] if states[i]["analyses_shared_with"] is not None else i
    final = first_of(results["states"][-1]["index"])
    first = first_of(next(s["index"] for s in results["states"] if s["analyses"]["mceip_mu"]["solutions"]))
    index = json.loads((out / "index.json").read_text())
    assert sorted(c["state"] for c in index["classifications"]) == sorted({final, first})
    assert not list(out.glob("*.mtx")) and not list(out.rglob("Kstar.mtx"))
    for c in index["classifications"]:
        for name in ("A0", "A1"):
            a = scipy.io.mmread(out / c["folder"] / f"{name}.mtx")
            b = scipy.io.mmread(full / c["folder"] / f"{name}.mtx")
            assert np.array_equal(np.asarray(a), np.asarray(b))
    p = run_cli_here("export", str(res), "--matrices", "-o", str(tmp_path / "none"), "--states", "100000")
    assert p.returncode == 2 and p.stderr.count("\n") == 1 and "--states" in p.stderr, p.stderr
    assert not (tmp_path / "none").exists()
