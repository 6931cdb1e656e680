"""A results folder is not trusted (issue 32): ``render`` and ``--overwrite`` write and delete only
the files the app recorded writing there, follow no symbolic link, write through no hard link,
build no path from results.json, never hang on a FIFO or allocate what a file's header claims,
and answer a malformed or oversized results.json with one ``error:`` line.

One small block study with plots, screenshots and the report is run once (module fixture); each
test copies its folder and changes the copy. Refusals are checked to leave every file as it was
(a hash of every path, hidden ones too) and to write nothing outside the folder. The cases that
could hang or exhaust memory run ``render`` in a child process under a time and an address-space
limit.
"""
from __future__ import annotations

import hashlib
import io
import json
import os
import pathlib
import resource
import shutil
import subprocess
import zipfile

import numpy as np
import pytest
import yaml
from conftest import PY, ROOT, one_error_line, run_cli, run_cli_here

SCENE = {
    "name": "hostile-folder",
    "system": {"type": "block", "nx": 4, "ny": 2},
    "mu": 1.1,
    "loading": {"normal_steps": 1, "tangential_step": 0.5, "tangential_max": 1.0},
    "analyses": ["necessary", "mceip_mu"],
    "outputs": {"plots": True, "report": True, "states": ["final"],
                "screenshots": {"resolution": [200, 120], "field": "displacement"}},
}
MARKER = ".contact-divergence.json"


@pytest.fixture(scope="module")
def made(tmp_path_factory) -> pathlib.Path:
    """The scene file's folder, holding the results folder ``out`` of one run."""
    d = tmp_path_factory.mktemp("hostile-folder")
    (d / "scene.yaml").write_text(yaml.safe_dump(SCENE, sort_keys=False))
    p = run_cli("run", str(d / "scene.yaml"), "-o", str(d / "out"), "-q")
    assert p.returncode == 0, p.stderr
    return d


@pytest.fixture
def out(made, tmp_path) -> pathlib.Path:
    """A copy of the results folder, in a folder of its own (``victim`` beside it stands for
    everything outside the results folder)."""
    shutil.copytree(made / "out", tmp_path / "out", symlinks=True)
    (tmp_path / "victim").mkdir()
    return tmp_path / "out"


def _snapshot(folder: pathlib.Path) -> dict:
    """Every path under ``folder`` (hidden ones too, links not followed) with its kind and a hash."""
    out = {}
    for p in sorted(folder.rglob("*")):
        if p.is_symlink():
            out[str(p.relative_to(folder))] = "link -> " + os.readlink(p)
        elif p.is_file():
            out[str(p.relative_to(folder))] = hashlib.sha256(p.read_bytes()).hexdigest()
        else:
            out[str(p.relative_to(folder))] = "dir" if p.is_dir() else "special"
    return out


def _marker(out: pathlib.Path) -> dict:
    return json.loads((out / MARKER).read_text())


def _set_marker(out: pathlib.Path, **change) -> None:
    (out / MARKER).write_text(json.dumps({**_marker(out), **change}))


def _edit_results(out: pathlib.Path, edit) -> None:
    doc = json.loads((out / "results.json").read_text())
    edit(doc)
    (out / "results.json").write_text(json.dumps(doc))


def _limited(gib: float):
    def apply():
        resource.setrlimit(resource.RLIMIT_AS, (int(gib * 2**30),) * 2)
        resource.setrlimit(resource.RLIMIT_CORE, (0, 0))
    return apply


def _render_child(out: pathlib.Path, seconds: float = 60, gib: float = 4) -> subprocess.CompletedProcess:
    """``python -m app render OUT`` in a child process limited to ``gib`` GiB of address space; a
    hang fails the test after ``seconds``."""
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    return subprocess.run([PY, "-m", "app", "render", str(out), "-q"], capture_output=True, text=True,
                          timeout=seconds, env=env, cwd=ROOT, preexec_fn=_limited(gib))


def _refused(out: pathlib.Path, *needles: str, child: bool = False) -> str:
    """Render refuses ``out`` with one error line holding ``needles``; nothing in or beside it changes."""
    before, beside = _snapshot(out), _snapshot(out.parent / "victim")
    proc = _render_child(out) if child else run_cli_here("render", str(out), "-q")
    line = one_error_line(proc)
    for n in needles:
        assert n in line, line
    assert _snapshot(out) == before and _snapshot(out.parent / "victim") == beside
    return line


# ---------------------------------------------------------------------------------------------
# Only the app's own files are written and deleted; no link is followed or written through


def test_the_marker_records_every_file_and_folder_the_app_wrote(made):
    out = made / "out"
    marker = _marker(out)
    files = sorted(p.relative_to(out).as_posix() for p in out.rglob("*") if p.is_file() and p.name != MARKER)
    folders = sorted(p.relative_to(out).as_posix() for p in out.rglob("*") if p.is_dir())
    assert marker["files"] == files and marker["folders"] == folders and marker["format"] == 2
    assert "plots/status_map.png" in files and "screenshots/state_0002_displacement.png" in files


def test_removing_old_results_deletes_only_the_recorded_files(out):
    """The previous results are deleted file by file from the marker's list (``--overwrite`` after the
    new results are in place): a file that appeared in the folder meanwhile, a symbolic link in place
    of a recorded file and what it points to all stay, and the folder is then kept."""
    from app.io.folder import remove_recorded
    outside = out.parent / "victim" / "mine.txt"
    outside.write_text("mine")
    (out / "plots" / "appeared.png").write_bytes(b"mine")
    (out / "steps.csv").unlink()
    (out / "steps.csv").symlink_to(outside)
    assert remove_recorded(out) is False
    left = sorted(p.relative_to(out).as_posix() for p in out.rglob("*"))
    assert left == ["plots", "plots/appeared.png", "steps.csv"], left
    assert outside.read_text() == "mine"


@pytest.mark.parametrize("name", ["plots", "screenshots", "fields"])
def test_render_refuses_a_linked_app_folder(out, name):
    """A picture folder that is a symbolic link is refused: the pictures it points to stay."""
    victim = out.parent / "victim"
    for p in (out / name).iterdir():
        shutil.copy(p, victim / p.name)
    shutil.rmtree(out / name)
    (out / name).symlink_to(victim)
    _refused(out, str(out / name), "symbolic link")
    assert sorted(p.name for p in victim.iterdir())


def test_render_never_writes_through_a_linked_report(out):
    victim = out.parent / "victim" / "notes.md"
    victim.write_text("my notes")
    (out / "report.md").unlink()
    (out / "report.md").symlink_to(victim)
    _refused(out, str(out / "report.md"), "not a file this app recorded writing")
    assert victim.read_text() == "my notes"


def test_render_replaces_a_hard_linked_report_by_a_new_file(out):
    """The report is replaced by a new file (rename): another name of the old one keeps its text."""
    other = out.parent / "victim" / "linked.md"
    os.link(out / "report.md", other)
    other.write_text("my notes")                       # the same inode as report.md
    p = run_cli_here("render", str(out), "-q")
    assert p.returncode == 0, p.stderr
    assert other.read_text() == "my notes"
    assert (out / "report.md").read_text().startswith("# Study report") and (out / "report.md").stat().st_nlink == 1


def test_render_keeps_a_users_files_in_the_apps_folders(out):
    """Files the app did not record (in plots/ and screenshots/) stay; the earlier pictures the app
    recorded and does not draw again are deleted, and the marker records what is there now."""
    mine = {out / "plots" / "mine.png": b"user plot", out / "screenshots" / "mine.png": b"user shot",
            out / "plots" / "notes.txt": b"user notes"}
    for path, data in mine.items():
        path.write_bytes(data)
    (out / "plots" / "old.png").write_bytes(b"an earlier drawing")
    _set_marker(out, files=sorted(_marker(out)["files"] + ["plots/old.png"]))
    p = run_cli_here("render", str(out), "-q")
    assert p.returncode == 0, p.stderr
    assert all(path.read_bytes() == data for path, data in mine.items())
    assert not (out / "plots" / "old.png").exists()
    marker = _marker(out)
    assert "plots/old.png" not in marker["files"] and "plots/mine.png" not in marker["files"]
    assert "plots/status_map.png" in marker["files"] and (out / "plots" / "status_map.png").stat().st_size > 1000
    assert [p.name for p in out.iterdir() if p.name.startswith(".render-")] == []


def test_render_refuses_a_users_file_where_a_picture_goes(out):
    """A file the app did not record, at the name of a picture it draws, is kept: nothing is redrawn."""
    (out / "plots" / "status_map.png").write_bytes(b"my own status map")
    _set_marker(out, files=[f for f in _marker(out)["files"] if f != "plots/status_map.png"])
    _refused(out, str(out / "plots" / "status_map.png"), "not a file this app recorded writing")


def test_render_builds_no_path_from_results_json(out):
    """``screenshots.field`` is one of the allowed fields (the name of a picture is made from it)."""
    def edit(doc):
        doc["scene_config"]["outputs"]["screenshots"]["field"] = "../../victim/x"
    _edit_results(out, edit)
    _refused(out, "results.json", "scene_config.outputs.screenshots.field", "'../../victim/x'")
    assert list(out.parent.rglob("*x.png")) == []


def test_a_folder_of_an_earlier_version_is_neither_redrawn_nor_replaced(made, out):
    """Format 1 recorded only top-level names: its files cannot be told from a user's."""
    marker = _marker(out)
    marker.pop("files"), marker.pop("folders")
    (out / MARKER).write_text(json.dumps({**marker, "format": 1}))
    _refused(out, "earlier version", "no usable list of its files")
    before = _snapshot(out)
    line = one_error_line(run_cli_here("run", str(made / "scene.yaml"), "-o", str(out), "-q", "--overwrite"))
    assert "earlier version" in line and _snapshot(out) == before


@pytest.mark.parametrize("bad", ["../victim/mine.txt", "/tmp/x", "plots/../../victim/mine.txt", "plots//x"])
def test_a_marker_listing_paths_outside_the_folder_is_not_used(made, out, bad):
    """A marker whose list names a path outside the folder (edited by hand, or by an attacker) is
    not a list the app writes: --overwrite and render refuse the folder, nothing is deleted."""
    (out.parent / "victim" / "mine.txt").write_text("mine")
    _set_marker(out, files=_marker(out)["files"] + [bad], folders=_marker(out)["folders"] + [".."])
    _refused(out, "no usable list of its files")
    before = _snapshot(out)
    line = one_error_line(run_cli_here("run", str(made / "scene.yaml"), "-o", str(out), "-q", "--overwrite"))
    assert "no usable list of its files" in line and _snapshot(out) == before
    assert (out.parent / "victim" / "mine.txt").read_text() == "mine"


def test_overwrite_refuses_a_folder_with_a_users_file_in_an_app_folder(made, out):
    """--overwrite replaces only a folder holding nothing but the app's recorded files; a file of
    the user's in plots/ or proofs/ refuses it, named, and nothing is touched."""
    (out / "plots" / "figure-for-paper.png").write_bytes(b"mine")
    (out / "proofs").mkdir()
    (out / "proofs" / "notes.txt").write_text("mine")
    before = _snapshot(out)
    line = one_error_line(run_cli_here("run", str(made / "scene.yaml"), "-o", str(out), "-q", "--overwrite"))
    assert "holds other files" in line and "plots/figure-for-paper.png" in line and "proofs/" in line
    assert _snapshot(out) == before


def test_a_sweep_replaces_a_case_folder_only_when_it_holds_only_recorded_files(out):
    """A case folder is replaced (a changed case scene, an earlier error) only when it holds nothing
    but what its marker records; its recorded files are then deleted one by one."""
    from app.study.sweep import _commit_case
    cases = out.parent / "cases"
    cases.mkdir()
    case = cases / "mu=1"
    shutil.copytree(out, case, symlinks=True)
    (case / "plots" / "mine.png").write_bytes(b"mine")
    staging = cases / ".mu=1.partial-1-1"
    staging.mkdir()
    (staging / "results.json").write_text("{}")
    before = _snapshot(case)
    why = _commit_case(staging, case)
    assert why is not None and "plots/mine.png" in why and str(staging) in why
    assert _snapshot(case) == before
    (case / "plots" / "mine.png").unlink()
    assert _commit_case(staging, case) is None
    assert sorted(p.name for p in case.iterdir()) == [MARKER, "results.json"]
    assert sorted(p.name for p in cases.iterdir()) == ["mu=1"]


# ---------------------------------------------------------------------------------------------
# Limits before work: no hang, no allocation a file's header claims


@pytest.mark.parametrize("name", ["fields/fields.npz", MARKER, "results.json"])
def test_render_does_not_hang_on_a_fifo(out, name):
    (out / name).unlink()
    os.mkfifo(out / name)
    line = one_error_line(_render_child(out, seconds=60))
    assert "FIFO" in line or "not a results folder written by this app" in line, line


def test_render_bounds_the_screenshot_resolution(out):
    def edit(doc):
        doc["scene_config"]["outputs"]["screenshots"]["resolution"] = [100000, 100000]
    _edit_results(out, edit)
    _refused(out, "scene_config.outputs.screenshots.resolution", "100000", "8192", child=True)


def test_render_refuses_an_oversized_results_json_unread(out):
    with open(out / "results.json", "r+b") as f:
        f.truncate(3 * 2**30)                          # sparse: 3 GiB of zeros
    _refused(out, str(out / "results.json"), "3.0 GiB", "is over the", child=True)


def _npy_header(shape: tuple, dtype=np.float64) -> bytes:
    buf = io.BytesIO()
    np.lib.format.write_array_header_1_0(buf, {"descr": np.dtype(dtype).str, "fortran_order": False,
                                               "shape": shape})
    return buf.getvalue()


@pytest.mark.parametrize("case", ["huge", "mismatch"])
def test_render_checks_the_npy_headers_before_loading(out, case):
    """A member claiming 1e6 x 1e6 numbers (8 TB), or more than it holds, is refused unread."""
    path = out / "fields" / "fields.npz"
    with zipfile.ZipFile(path) as z:
        members = {n: z.read(n) for n in z.namelist()}
    shape = (10**6, 10**6) if case == "huge" else (1000, 2)
    members["state_u.npy"] = _npy_header(shape) + b"\0" * (64 if case == "huge" else 800)
    with zipfile.ZipFile(path, "w") as z:
        for n, data in members.items():
            z.writestr(n, data)
    _refused(out, str(path), "state_u.npy", "(1000000, 1000000)" if case == "huge" else "(1000, 2)", child=True)


# ---------------------------------------------------------------------------------------------
# A malformed results.json is one error line naming the file and the key


def _state0(doc):
    return doc["states"][0]


MALFORMED = {
    "list at top level": lambda doc: [doc],
    "states not a list": lambda doc: {**{k: v for k, v in doc.items() if k != "non_finite"}, "states": 5},
    "analyses a string": lambda doc: (_state0(doc).update(analyses="x"), doc)[1],
    "nodes not records": lambda doc: (_state0(doc).update(nodes=[1, 2]), doc)[1],
    "scene_config a list": lambda doc: {**doc, "scene_config": []},
    "outputs.notes a number": lambda doc: {**doc, "outputs": {"notes": 5}},
    "pictured states not a list": lambda doc: (doc["scene_config"]["outputs"].update(states="final"), doc)[1],
    "a string for a number": lambda doc: (_state0(doc)["nodes"][0].update(u_N="inf"), doc)[1],
    # the bounds of (19) where its budget was spent: a pair of numbers, never a path or anything longer
    "bounds a path": lambda doc: (_state0(doc)["analyses"]["necessary"].update(min_eig_K_sym_bounds="../victim/x"),
                                  doc)[1],
    "bounds of three numbers": lambda doc: (_state0(doc)["analyses"]["necessary"].update(
        min_eig_M_sym_bounds=[0.0, 1.0, 2.0]), doc)[1],
}
KEYS = {"list at top level": "the document", "states not a list": "states", "analyses a string": "states.0.analyses",
        "nodes not records": "states.0.nodes.0", "scene_config a list": "scene_config",
        "outputs.notes a number": "outputs.notes", "pictured states not a list": "scene_config.outputs.states",
        "a string for a number": "states.0.nodes.0.u_N", "bounds a path": "states.0.analyses.necessary.min_eig_K_sym_bounds",
        "bounds of three numbers": "states.0.analyses.necessary.min_eig_M_sym_bounds"}


@pytest.mark.parametrize("case", sorted(MALFORMED))
def test_render_malformed_results_json_is_one_line(out, case):
    doc = MALFORMED[case](json.loads((out / "results.json").read_text()))
    (out / "results.json").write_text(json.dumps(doc))
    _refused(out, str(out / "results.json"), KEYS[case])


@pytest.mark.parametrize("where", ["top", "inside"])
def test_render_deeply_nested_results_json_is_one_line(out, where):
    deep = "[" * 100_000 + "]" * 100_000
    if where == "top":
        (out / "results.json").write_text(deep)
    else:
        text = (out / "results.json").read_text()
        (out / "results.json").write_text(text.replace('"scene_config": {', '"scene_config": {"deep": ' + deep + ", ", 1))
    _refused(out, str(out / "results.json"))


# --- a sweep folder resumed in place ----------------------------------------------------------------

SWEEP = ("name: sw\nsystem: {type: two_particles, k: 1000.0, m: 2.0, phi_deg: 35.0, signs: [1, -1]}\n"
         "mu: 2.5\nanalyses: [mceip_mu]\nsweep: {parameters: {mu: [1.0, 2.0]}}\n")


@pytest.fixture(scope="module")
def sweep_folder(tmp_path_factory):
    """A finished two-case sweep (its folder is resumed and written in place)."""
    tmp = tmp_path_factory.mktemp("sweep")
    (tmp / "sw.yaml").write_text(SWEEP)
    assert run_cli_here("run", str(tmp / "sw.yaml"), "-o", str(tmp / "out"), "-q").returncode == 0
    assert (tmp / "out" / "plots").is_dir() and (tmp / "out" / "sweep.log").is_file()
    return tmp


@pytest.mark.parametrize("name", ["sweep.log", "plots", "sweep.csv"])
def test_a_sweep_writes_through_no_link_in_its_folder(sweep_folder, tmp_path, name):
    """A resumed sweep whose ``sweep.log``, ``plots/`` or ``sweep.csv`` is a symbolic link (to a user's
    file or folder) is refused with one line, and the user's file is unchanged."""
    out = tmp_path / "out"
    shutil.copytree(sweep_folder / "out", out)
    target = tmp_path / "users"
    if name == "plots":
        target.mkdir()
        (target / "mu.png").write_bytes(b"mine")
    else:
        target.write_text("my own notes\n")
    path = out / name
    shutil.rmtree(path) if path.is_dir() else path.unlink()
    path.symlink_to(target)
    before = _tree(tmp_path / "users") if name == "plots" else target.read_bytes()
    line = one_error_line(run_cli_here("run", str(sweep_folder / "sw.yaml"), "-o", str(out), "-q", "--overwrite"))
    assert "symbolic link" in line and name in line
    assert (_tree(target) if name == "plots" else target.read_bytes()) == before


def test_a_sweep_log_with_another_hard_link_is_not_appended_to(sweep_folder, tmp_path):
    out = tmp_path / "out"
    shutil.copytree(sweep_folder / "out", out)
    mine = tmp_path / "mine.txt"
    mine.write_text("my own notes\n")
    (out / "sweep.log").unlink()
    os.link(mine, out / "sweep.log")
    line = one_error_line(run_cli_here("run", str(sweep_folder / "sw.yaml"), "-o", str(out), "-q", "--overwrite"))
    assert "hard links" in line
    assert mine.read_text() == "my own notes\n"


def test_a_sweep_does_not_hang_on_a_fifo_in_a_case_folder(sweep_folder, tmp_path):
    """A FIFO in place of a case's results.json: the case is not taken as complete, and nothing waits on it."""
    out = tmp_path / "out"
    shutil.copytree(sweep_folder / "out", out)
    case = next((out / "cases").iterdir())
    (case / "results.json").unlink()
    os.mkfifo(case / "results.json")
    p = run_cli("run", str(sweep_folder / "sw.yaml"), "-o", str(out), timeout=300)
    assert "Traceback" not in p.stdout + p.stderr and "1 skipped" in p.stdout, p.stdout + p.stderr
    assert stat_is_fifo(case / "results.json")          # a foreign file in the case folder: kept


def stat_is_fifo(path: pathlib.Path) -> bool:
    import stat
    return stat.S_ISFIFO(os.lstat(path).st_mode)


def _tree(folder: pathlib.Path) -> dict:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}
