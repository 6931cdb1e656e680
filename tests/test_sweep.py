"""Parameter sweeps (app/study/sweep.py): expansion into named cases, bad sweep sections, the MPI task
farm (same per-case numbers on 1 rank and on 3 ranks in groups), restart after a kill."""
from __future__ import annotations

import json
import os
import pathlib
import re
import shutil
import signal
import subprocess
import time

import pytest
import yaml
from conftest import PY, ROOT, run_cli_here
from mpi4py import MPI

# 6 cases of the block on a small mesh, MCEIP-mu only: about 1 s each
SWEEP = """\
name: sweep-check
system: {type: block, nx: 10, ny: 5}
mu: 1.1
analyses: [mceip_mu]
loading: {tangential_step: 0.05}
sweep:
  mode: product
  parameters:
    mu: [0.8, 1.1]
    system.length: {start: 40, stop: 80, num: 3}
"""
NAMES = [f"mu={m}_system.length={L}" for m in ("0.8", "1.1") for L in (40, 60, 80)]
TWO = """\
name: two-sweep
system: {type: two_particles, k: 1000.0, m: 2.0, phi_deg: 35.0, signs: [1, -1]}
mu: 2.5
analyses: [mceip_mu, enumerate]
"""
NOT_COMPARED = {"wall_seconds", "ran", "ranks"}


def _scene(text: str):
    from app.scene.schema import parse_scene
    return parse_scene(yaml.safe_load(text), "s.yaml")


def _env():
    return dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
                OMPI_MCA_rmaps_base_oversubscribe="1", PYTHONPATH=str(ROOT))


# ------------------------------------------------------------------------------ expansion


def test_product_expands_in_order_with_stable_names():
    from app.study.sweep import expand
    cases = expand(_scene(SWEEP))
    assert [c.name for c in cases] == NAMES
    assert [c.index for c in cases] == list(range(6))
    assert [(c.scene.mu, c.scene.system.length) for c in cases] == [
        (m, L) for m in (0.8, 1.1) for L in (40.0, 60.0, 80.0)]
    c = cases[4]
    assert c.values == {"mu": 1.1, "system.length": 60}
    assert c.scene.sweep is None and c.scene.system.nx == 10 and c.scene.loading.tangential_step == 0.05
    assert c.scene.name == "sweep-check"
    # the same scene gives the same names and hashes; a changed value changes only that case's hash
    again = expand(_scene(SWEEP))
    assert [c.scene_hash for c in again] == [c.scene_hash for c in cases]
    assert len({c.scene_hash for c in cases}) == 6
    other = expand(_scene(SWEEP.replace("mu: [0.8, 1.1]", "mu: [0.8, 1.2]")))
    assert [a.scene_hash == b.scene_hash for a, b in zip(cases, other)] == [True] * 3 + [False] * 3


def test_zip_ranges_and_nested_keys():
    from app.study.sweep import expand
    text = SWEEP.split("sweep:")[0] + """\
sweep:
  mode: zip
  parameters:
    system.length: {start: 40, stop: 120, step: 20}
    system.nx: [10, 15, 20, 25, 30]
    settings.mcp.starts: [[1.0], [2.0], [0.5, 3], [4.0], [5.0]]
"""
    cases = expand(_scene(text))
    assert [(c.scene.system.length, c.scene.system.nx) for c in cases] == [
        (40, 10), (60, 15), (80, 20), (100, 25), (120, 30)]
    assert cases[2].scene.settings.mcp.starts == [0.5, 3.0]
    assert cases[2].name == "system.length=80_system.nx=20_settings.mcp.starts=0.5,3"
    # float ranges are rounded to 12 significant digits: clean names
    s = _scene(TWO + "sweep: {parameters: {mu: {start: 0.1, stop: 0.3, step: 0.1}}}\n")
    assert [c.name for c in expand(s)] == ["mu=0.1", "mu=0.2", "mu=0.3"]
    s = _scene(TWO + "sweep: {parameters: {mu: {start: 1, stop: 2, num: 3}}}\n")
    assert s.sweep.parameters["mu"] == [1.0, 1.5, 2.0]


BAD_SWEEPS = [
    ("unknown_key", "sweep: {parameters: {system.lenght: [40, 60]}}",
     ("sweep.parameters.system.lenght = [40, 60]", "'lenght' is not a key of system (block)", "length")),
    ("key_below_value", "sweep: {parameters: {mu.x: [1, 2]}}", ("sweep.parameters.mu.x", "not a section")),
    ("unknown_sweep_key", "sweep: {parameters: {mu: [1]}, modes: zip}", ("unknown key 'sweep.modes'",)),
    ("bad_mode", "sweep: {mode: grid, parameters: {mu: [1]}}", ("sweep.mode = 'grid'", "'product' or 'zip'")),
    ("scalar_values", "sweep: {parameters: {mu: 1.1}}", ("sweep.parameters.mu = 1.1", "list of values", "range")),
    ("empty_list", "sweep: {parameters: {mu: []}}", ("sweep.parameters.mu = []", "non-empty list")),
    ("no_parameters", "sweep: {parameters: {}}", ("sweep.parameters = {}", "one or more")),
    ("missing_parameters", "sweep: {mode: zip}", ("missing key 'sweep.parameters'",)),
    ("range_without_num", "sweep: {parameters: {mu: {start: 1, stop: 2}}}", ("sweep.parameters.mu", "num")),
    ("range_bad_key", "sweep: {parameters: {mu: {start: 1, stop: 2, n: 3}}}", ("unknown range key 'n'",)),
    ("zip_lengths", "sweep: {mode: zip, parameters: {mu: [1, 2], system.nx: [4, 5, 6]}}",
     ("sweep.parameters =", "same number of values")),
    ("duplicate_value", "sweep: {parameters: {mu: [1.1, 1.1]}}", ("sweep.parameters.mu", "listed twice")),
    ("name_swept", "sweep: {parameters: {name: [a, b]}}", ("sweep.parameters.name", "cannot be swept")),
    ("mapping_value", "sweep: {parameters: {system: [{nx: 4}]}}", ("sweep.parameters.system", "not allowed")),
    ("overlapping_keys", "sweep: {parameters: {loading: [null], loading.normal_steps: [2]}}",
     ("sweep.parameters.loading.normal_steps", "inside the swept key 'loading'")),
    ("invalid_case", "sweep: {parameters: {mu: [1.0], system.nx: [10, 0]}}",
     ("sweep case 'mu=1_system.nx=0'", "system.nx = 0", "greater than or equal to 1")),
    ("same_case_name", "sweep: {parameters: {system.length: [80, 80.0]}}", ("same name 'system.length=80'",)),
]


@pytest.fixture(scope="module")
def bad_sweep_outcomes(tmp_path_factory):
    root = tmp_path_factory.mktemp("badsweep")
    base = SWEEP.split("sweep:")[0]
    jobs = {}
    for bad_id, line, _ in BAD_SWEEPS:
        path = root / f"{bad_id}.yaml"
        path.write_text(base + line + "\n")
        jobs[bad_id, "validate"] = ("validate", str(path))
    jobs["unknown_key", "run"] = ("run", str(root / "unknown_key.yaml"), "-o", str(root / "out"), "-q")
    jobs["invalid_case", "run"] = ("run", str(root / "invalid_case.yaml"), "-o", str(root / "out"), "-q")
    return root, {k: run_cli_here(*args) for k, args in jobs.items()}   # user errors: in this process


@pytest.mark.parametrize("bad", BAD_SWEEPS, ids=[b[0] for b in BAD_SWEEPS])
def test_bad_sweep_is_a_one_line_user_error(bad, bad_sweep_outcomes):
    root, outcomes = bad_sweep_outcomes
    for key in [(bad[0], "validate"), (bad[0], "run")]:
        if key not in outcomes:
            continue
        p = outcomes[key]
        assert p.returncode == 2, (p.returncode, p.stdout, p.stderr)
        assert "Traceback" not in p.stderr and p.stdout == ""
        lines = p.stderr.splitlines()
        assert len(lines) == 1 and lines[0].startswith("error: "), p.stderr
        for needle in bad[2]:
            assert needle in lines[0], (needle, lines[0])
    assert not (root / "out").exists()           # nothing ran, nothing was written


def test_validate_lists_the_cases(tmp_path):
    (tmp_path / "s.yaml").write_text(SWEEP)
    p = run_cli_here("validate", str(tmp_path / "s.yaml"))
    assert p.returncode == 0, p.stderr
    assert "sweep 'sweep-check' of 6 case(s)" in p.stdout and NAMES[0] in p.stdout


def test_ranks_per_case_needs_a_sweep_and_enough_ranks(tmp_path):
    (tmp_path / "one.yaml").write_text(TWO)
    p = run_cli_here("run", str(tmp_path / "one.yaml"), "--ranks-per-case", "2", "-o", str(tmp_path / "o"))
    assert p.returncode == 2 and "only for a scene with a 'sweep' section" in p.stderr
    (tmp_path / "s.yaml").write_text(SWEEP)
    p = run_cli_here("run", str(tmp_path / "s.yaml"), "--ranks-per-case", "2", "-o", str(tmp_path / "o"))
    assert p.returncode == 2 and "1 to the number of MPI ranks (1)" in p.stderr


# ------------------------------------------------------------------------------ running (in process)


@pytest.mark.skipif(MPI.COMM_WORLD.size > 1, reason="runs the serial sweep in this process")
def test_two_particle_sweep_table_restart_and_changed_case(tmp_path):
    """Table rows against the per-case results.json; a second run skips everything; a case whose
    scene changed (hash) is run again, the others are not."""
    from app.study.sweep import expand, run_sweep
    text = TWO + "sweep: {parameters: {system.signs: [[1, -1], [1, 1], [-1, 1]]}}\n"
    scene = _scene(text)
    cases = expand(scene)
    assert [c.name for c in cases] == ["system.signs=1,-1", "system.signs=1,1", "system.signs=-1,1"]
    assert run_sweep(scene, cases, MPI.COMM_WORLD, tmp_path, quiet=True) == 0
    doc = json.loads((tmp_path / "sweep.json").read_text())
    assert doc["complete"] and doc["n_cases"] == 3 and doc["missing"] == []
    for c, row in zip(cases, doc["cases"]):
        res = json.loads((tmp_path / "cases" / c.name / "results.json").read_text())
        assert res["sweep_case"]["scene_hash"] == c.scene_hash
        sols = res["states"][0]["analyses"]["mceip_mu"]["solutions"]
        assert row["final_mceip_mu_count"] == len(sols)
        assert row["final_mceip_mu_min"] == (min(s["value"] for s in sols) if sols else None)
        assert row["status"] == "ok" and row["ran"] == "this run" and row["n_states"] == 1
        assert row["system.signs"] == ",".join(str(s) for s in c.values["system.signs"])
    # Table 1 of the paper: S1 = -1, S2 = +1 has no solution; the other two have some
    assert [r["final_mceip_mu_count"] > 0 for r in doc["cases"]] == [True, True, False]
    assert (tmp_path / "plots" / "system.signs.png").stat().st_size > 1000
    csv_lines = (tmp_path / "sweep.csv").read_text().splitlines()
    assert len(csv_lines) == 4 and csv_lines[0].startswith("case,index,system.signs,status,")
    assert ",final_u_x [mm]," in csv_lines[0] and ",first_mceip_mu_u_x [mm]," in csv_lines[0]
    assert doc["units"]["length"] == "mm" and "[length]" in doc["columns"]["final_u_x"]

    mtimes = {c.name: (tmp_path / "cases" / c.name / "results.json").stat().st_mtime_ns for c in cases}
    assert run_sweep(scene, cases, MPI.COMM_WORLD, tmp_path, quiet=True) == 0
    doc = json.loads((tmp_path / "sweep.json").read_text())
    assert [r["ran"] for r in doc["cases"]] == ["earlier"] * 3
    changed = _scene(text.replace("[-1, 1]]", "[-1, -1]]"))
    cases2 = expand(changed)
    run_sweep(changed, cases2, MPI.COMM_WORLD, tmp_path, quiet=True)
    doc = json.loads((tmp_path / "sweep.json").read_text())
    assert [r["ran"] for r in doc["cases"]] == ["earlier", "earlier", "this run"]
    assert all((tmp_path / "cases" / n / "results.json").stat().st_mtime_ns == t
               for n, t in mtimes.items() if n != "system.signs=-1,1")
    # a half-written case (no results.json, e.g. killed while writing) is run again
    (tmp_path / "cases" / "system.signs=1,1" / "results.json").unlink()
    run_sweep(changed, cases2, MPI.COMM_WORLD, tmp_path, quiet=True)
    doc = json.loads((tmp_path / "sweep.json").read_text())
    assert [r["ran"] for r in doc["cases"]] == ["earlier", "this run", "earlier"]


# ------------------------------------------------------------------------------ MPI task farm


def _rows(outdir: pathlib.Path) -> dict[str, dict]:
    doc = json.loads((outdir / "sweep.json").read_text())
    assert doc["complete"], doc["missing"]
    return {r["case"]: r for r in doc["cases"]}


def _log(outdir: pathlib.Path) -> list[list[str]]:
    """sweep.log as fields: time, event, case, details (a line cut by a kill is skipped)."""
    return [ln.split("\t") for ln in (outdir / "sweep.log").read_text().splitlines() if ln.count("\t") >= 2]


def _assert_same_rows(a: dict, b: dict) -> None:
    assert list(a) == list(b)
    for name in a:
        for col, va in a[name].items():
            if col in NOT_COMPARED:
                continue
            vb = b[name][col]
            if isinstance(va, float):
                assert vb == pytest.approx(va, rel=1e-8), (name, col)
            else:
                assert va == vb, (name, col)


@pytest.fixture(scope="module")
def serial_sweep(tmp_path_factory):
    d = tmp_path_factory.mktemp("sweep")
    (d / "s.yaml").write_text(SWEEP)
    p = run_cli_here("run", str(d / "s.yaml"), "-o", str(d / "n1"), "-q")
    assert p.returncode == 0, p.stderr
    return d, _rows(d / "n1")


@pytest.mark.mpi
@pytest.mark.slow
@pytest.mark.skipif(shutil.which("mpirun") is None, reason="mpirun not found")
@pytest.mark.skipif(MPI.COMM_WORLD.size > 1, reason="launches mpirun itself")
@pytest.mark.parametrize("ranks_per_case,dispatcher", [(1, ""), (2, ""), (1, "dedicated")],
                         ids=["3x1", "2+1", "dedicated-dispatcher"])
def test_same_numbers_on_one_rank_and_on_three(serial_sweep, ranks_per_case, dispatcher):
    d, ref = serial_sweep
    assert list(ref) == NAMES and all(r["status"] == "ok" for r in ref.values())
    assert all(r["final_mceip_mu_min"] is not None and r["first_mceip_mu_state"] is not None for r in ref.values())
    out = d / f"n3-{ranks_per_case}-{dispatcher}"
    env = _env()
    if dispatcher:
        env["CONTACT_DIVERGENCE_SWEEP_DISPATCHER"] = dispatcher
    p = subprocess.run(["mpirun", "--oversubscribe", "-n", "3", PY, "-m", "app", "run", str(d / "s.yaml"),
                        "-o", str(out), "--ranks-per-case", str(ranks_per_case)],
                       capture_output=True, text=True, timeout=600, env=env, cwd=ROOT)
    assert p.returncode == 0, p.stderr
    assert p.stdout.count("sweep 'sweep-check': 6 cases") == 1      # only rank 0 prints
    rows = _rows(out)
    _assert_same_rows(ref, rows)
    groups = {1: {"": 3, "dedicated": 2}, 2: {"": 2}}[ranks_per_case][dispatcher]
    doc = json.loads((out / "sweep.json").read_text())
    assert f"{groups} group(s) of up to {ranks_per_case} rank(s)" in doc["scheduler"]
    assert ("dedicated" in doc["scheduler"]) == bool(dispatcher)
    assert {r["ranks"] for r in rows.values()} <= {1, 2} and all(r["ran"] == "this run" for r in rows.values())
    started = [f for f in _log(out) if f[1] == "start"]
    assert sorted(s[2] for s in started) == sorted(NAMES)                 # each case handed out once
    assert len({s[3] for s in started}) == groups                          # and every group got work


@pytest.mark.mpi
@pytest.mark.slow
@pytest.mark.skipif(shutil.which("mpirun") is None, reason="mpirun not found")
@pytest.mark.skipif(MPI.COMM_WORLD.size > 1, reason="launches mpirun itself")
def test_killed_sweep_finishes_only_the_missing_cases(serial_sweep, tmp_path):
    d, ref = serial_sweep
    (tmp_path / "s.yaml").write_text(SWEEP)
    out = tmp_path / "out"
    cmd = ["mpirun", "--oversubscribe", "-n", "2", PY, "-m", "app", "run", str(tmp_path / "s.yaml"),
           "-o", str(out), "-q"]
    p = subprocess.Popen(cmd, env=_env(), cwd=ROOT, start_new_session=True,
                         stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    t0 = time.monotonic()
    try:
        # a case's results.json is written by its group before rank 0 hears of it and rewrites
        # sweep.json: wait for both, so that the kill comes after sweep.json's first version
        while len(list(out.glob("cases/*/results.json"))) < 2 or not (out / "sweep.json").exists():
            assert p.poll() is None, "the sweep ended before it could be killed"
            assert time.monotonic() - t0 < 300
            time.sleep(0.02)
    finally:
        os.killpg(p.pid, signal.SIGKILL)                 # mpirun and its ranks, without warning
        p.wait(timeout=60)
        # OpenMPI may put the ranks in process groups of their own: kill them too, and wait
        # until none is left, so that no orphaned rank finishes a case after the count below.
        pattern = str(tmp_path / "s.yaml")
        for _ in range(600):
            subprocess.run(["pkill", "-KILL", "-f", pattern], capture_output=True)
            if subprocess.run(["pgrep", "-f", pattern], capture_output=True).returncode != 0:
                break
            time.sleep(0.05)
    time.sleep(0.5)
    done = {x.parent.name: x.stat().st_mtime_ns for x in out.glob("cases/*/results.json")}
    assert 2 <= len(done) < 6, done
    assert not json.loads((out / "sweep.json").read_text())["complete"]

    p = subprocess.run(cmd, env=_env(), cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert p.returncode == 0, p.stderr
    rows = _rows(out)
    assert {n for n, r in rows.items() if r["ran"] == "earlier"} == set(done)
    assert {n for n, r in rows.items() if r["ran"] == "this run"} == set(NAMES) - set(done)
    # the finished cases were not touched; the log of the second run starts only the missing ones
    assert {x.parent.name: x.stat().st_mtime_ns for x in out.glob("cases/*/results.json")
            if x.parent.name in done} == done
    log = _log(out)
    second = log[max(i for i, f in enumerate(log) if f[1] == "sweep"):]
    assert sorted(f[2] for f in second if f[1] == "start") == sorted(set(NAMES) - set(done))
    assert sorted(f[2] for f in second if f[1] == "skip") == sorted(done)
    _assert_same_rows(ref, rows)                          # and the combined table is complete and right
    assert (out / "plots" / "mu.png").exists() and (out / "plots" / "system.length.png").exists()


def test_swept_file_paths_are_relative_to_the_scene_file(tmp_path):
    """A swept file key (system.file of a gmsh scene) is resolved against the scene's folder, as the
    same key written in the scene; it used to be resolved against the current folder."""
    geo = (ROOT / "app" / "scenes" / "gmsh" / "block.geo").read_text()
    (tmp_path / "sub").mkdir()
    for nx in (10, 20):
        (tmp_path / "sub" / f"b{nx}.geo").write_text(geo.replace("nx = 20; ny = 10;", f"nx = {nx}; ny = {nx // 2};"))
    scene = (ROOT / "app" / "scenes" / "gmsh" / "block.yaml").read_text().replace("file: block.geo", "file: sub/b20.geo")
    scene = re.sub(r"^outputs:.*$", "", scene, flags=re.M)
    (tmp_path / "s.yaml").write_text(scene + "sweep:\n  parameters:\n    system.file: [sub/b10.geo, sub/b20.geo]\n")
    p = run_cli_here("validate", str(tmp_path / "s.yaml"), cwd="/")
    assert p.returncode == 0, p.stderr
    assert "of 2 case(s)" in p.stdout and "system.file=sub-b10.geo" in p.stdout, p.stdout
    (tmp_path / "s2.yaml").write_text(scene + "sweep:\n  parameters:\n    system.file: [sub/nope.geo]\n")
    p = run_cli_here("validate", str(tmp_path / "s2.yaml"), cwd="/")
    assert p.returncode == 2 and str(tmp_path / "sub" / "nope.geo") in p.stderr, p.stderr


def test_a_case_folder_is_replaced_only_when_it_holds_only_app_files(tmp_path):
    """A rerun case replaces its earlier folder when that holds only what the app writes; a file
    of the user's in it keeps the folder (and the new results stay in the staging folder)."""
    from app.io.folder import seal
    from app.study.sweep import _commit_case
    cases = tmp_path / "cases"
    (cases / "a" / "proofs").mkdir(parents=True)
    (cases / "a" / "results.json").write_text("old")
    (cases / "a" / "proofs" / "state_1.npz").write_text("old")
    seal(cases / "a")                                  # as a run of the sweep leaves it: every file recorded
    new = cases / ".a.partial-1-1"
    new.mkdir()
    (new / "results.json").write_text("new")
    assert _commit_case(new, cases / "a") is None
    assert (cases / "a" / "results.json").read_text() == "new" and not (cases / "a" / "proofs").exists()
    assert sorted(p.name for p in cases.iterdir()) == ["a"]
    (cases / "a" / "notes.txt").write_text("mine")
    again = cases / ".a.partial-1-2"
    again.mkdir()
    (again / "results.json").write_text("newer")
    why = _commit_case(again, cases / "a")
    assert why is not None and "notes.txt" in why and str(again) in why
    assert (cases / "a" / "notes.txt").read_text() == "mine" and (cases / "a" / "results.json").read_text() == "new"
    assert (again / "results.json").read_text() == "newer"


def test_a_signal_a_library_wrapped_while_a_case_is_written_is_the_interrupt(tmp_path, monkeypatch):
    """A SIGTERM that lands inside pydantic's serialisation of results.json reaches the sweep as a
    PydanticSerializationError wrapping the KeyboardInterrupt (seen with Ctrl-C under mpirun): the
    case is the interrupt (nothing of it left), not a failed case with a traceback."""
    from app.common import interrupt
    from app.study import driver, sweep
    case = sweep.expand(_scene(TWO.replace("analyses: [mceip_mu, enumerate]", "analyses: [mceip_mu]")
                               + "sweep: {mode: product, parameters: {mu: [2.5]}}\n"))[0]

    def wrapped(*args, **kwargs):
        interrupt.record(15)
        raise ValueError("Error calling function `_listed`: KeyboardInterrupt: signal 15")

    monkeypatch.setattr(driver, "run_and_write", wrapped)
    try:
        with pytest.raises(KeyboardInterrupt):
            sweep.run_case(case, MPI.COMM_SELF, tmp_path)
    finally:
        interrupt.clear()
    assert not [p for p in tmp_path.rglob("*") if p.is_file()]
