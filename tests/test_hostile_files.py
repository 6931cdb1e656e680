"""A user's Gmsh files are data, never code (issue 19): the .geo allowlist, the .msh header
check, the sandboxed Gmsh child and its limits.

Every refused file must leave the disk unchanged (a marker file the script would create stays
absent) on ``validate`` and on ``run``, and give one ``error:`` line naming the command and its
line; the hang cases end within the limit; a fuzz of mutated .msh files never crashes this
process and never gives a traceback.
"""
from __future__ import annotations

import pathlib
import random
import time

import pytest
from conftest import one_error_line, run_cli, run_cli_here

BODY = """\
L = 10; H = 5;
Point(1) = {0, 0, 0, 2.5}; Point(2) = {L, 0, 0, 2.5}; Point(3) = {L, H, 0, 2.5}; Point(4) = {0, H, 0, 2.5};
Line(1) = {1, 2}; Line(2) = {2, 3}; Line(3) = {3, 4}; Line(4) = {4, 1};
Curve Loop(1) = {1, 2, 3, 4};
Plane Surface(1) = {1};
Physical Curve("AB") = {1};
Physical Curve("CD") = {3};
Physical Surface("block") = {1};
"""
SCENE = """\
name: hostile
system:
  type: gmsh
  file: FILE
  contact: AB
  prescribed: {CD: xy}
  material: {E: 5.0, nu: 0.48}
  program:
    - {steps: 2, displacement: {CD: {translation: [0, -0.01]}}}
mu: 0.5
analyses: [mceip_mu]
SETTINGS
"""

# (statement with MARKER for the marker file's path, the word the error must name)
REFUSED = [
    ('SystemCall "touch MARKER";', "SystemCall"),
    ('NonBlockingSystemCall "touch MARKER";', "NonBlockingSystemCall"),
    ('OnelabRun("x", "touch MARKER");', "OnelabRun"),
    ('Printf("x") > "MARKER";', "Printf"),
    ('Printf("x %g", 1) >> "MARKER";', "Printf"),
    ('Save "MARKER";', "Save"),
    ('Print "MARKER";', "Print"),
    ('Merge "/dev/zero";', "Merge"),
    ('Include "/etc/hostname";', "Include"),
    ('Exit;', "Exit"),
    ('Sleep 1000;', "Sleep"),
    ('Plugin(Crack).Run;', "Plugin"),
    ('CreateDir "MARKER";', "CreateDir"),
    ('DeleteFile "MARKER";', "DeleteFile"),
    ('Solver.Executable0 = "touch MARKER";', "Solver.Executable0"),
    ('General.Terminal = 1;', "General.Terminal"),
    ('For i In {1:1e15}\nEndFor', "For"),
    ('n = 1e9; For (1:n)\nEndFor', "For"),
    ('Touch "MARKER";', "Touch"),
]


def _write(tmp_path: pathlib.Path, geo: str, settings: str = "", name: str = "body.geo") -> pathlib.Path:
    (tmp_path / name).write_text(geo)
    scene = tmp_path / "scene.yaml"
    scene.write_text(SCENE.replace("FILE", name).replace("SETTINGS", settings))
    return scene


@pytest.mark.parametrize("statement, word", REFUSED, ids=[w + str(i) for i, (_, w) in enumerate(REFUSED)])
def test_refused_geo_commands_change_nothing(tmp_path, statement, word):
    """Each refused command: one SceneError naming it and its line; the marker stays absent."""
    from app.scene.schema import SceneError, load_scene
    marker = tmp_path / "MARKER"
    scene = _write(tmp_path, BODY + statement.replace("MARKER", str(marker)) + "\n")
    with pytest.raises(SceneError) as err:
        load_scene(scene)
    msg = str(err.value)
    assert word in msg and "line 9" in msg and "system.file" in msg, msg
    assert not marker.exists()


@pytest.mark.parametrize("command", ["validate", "run"])
@pytest.mark.parametrize("statement", ['SystemCall "touch MARKER";', 'Printf("x") > "MARKER";',
                                       'Save "MARKER";', 'NonBlockingSystemCall "touch MARKER";'])
def test_cli_refuses_geo_and_marker_stays_absent(tmp_path, command, statement):
    marker = tmp_path / "MARKER"
    scene = _write(tmp_path, BODY + statement.replace("MARKER", str(marker)) + "\n")
    before = sorted(p.name for p in tmp_path.iterdir())
    args = [command, str(scene)] + (["-o", str(tmp_path / "out")] if command == "run" else [])
    line = one_error_line(run_cli_here(*args, cwd=tmp_path))
    assert "line 9" in line
    assert not marker.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == before


def test_allowed_geo_still_runs(tmp_path):
    """Terminal Printf, options, loops, If, a macro and an Include inside the folder pass."""
    from app.scene.schema import load_scene
    (tmp_path / "sizes.geo").write_text("lc = 2.5; // sizes\n")
    geo = ('Include "sizes.geo";\nMesh.Algorithm = 6; Geometry.Tolerance = 1e-9;\nPrintf("lc = %g", lc);\n'
           'For i In {1:3}\n  If (i == 2)\n    x = i;\n  EndIf\nEndFor\n' + BODY.replace("2.5}", "lc}"))
    scene = load_scene(_write(tmp_path, geo))
    assert scene.system.contact == "AB"


def test_include_outside_the_folder_is_refused(tmp_path):
    from app.scene.schema import SceneError, load_scene
    sub = tmp_path / "scene"
    sub.mkdir()
    (tmp_path / "outside.geo").write_text("lc = 1;\n")
    with pytest.raises(SceneError, match="outside the scene's folder"):
        load_scene(_write(sub, 'Include "../outside.geo";\n' + BODY))


def test_msh_that_is_a_script_is_refused(tmp_path):
    """A .msh not starting with $MeshFormat would be run by Gmsh as a script."""
    marker = tmp_path / "MARKER"
    scene = _write(tmp_path, BODY + f'SystemCall "touch {marker}";\nMesh 2;\n', name="body.msh")
    line = one_error_line(run_cli_here("validate", str(scene), cwd=tmp_path))
    assert "$MeshFormat" in line and not marker.exists()


@pytest.mark.parametrize("settings, geo_extra, words", [
    # a loop whose bound is not known to the allowlist: ended by the time limit
    ("settings: {limits: {max_file_seconds: 2}}", "x[] = {1e15};\nFor i In {1:x[0]}\nEndFor\n", "max_file_seconds"),
    # a mesh far too fine: refused from the counted curve nodes, before the surfaces are meshed
    ("settings: {limits: {max_dofs: 2000}}", "Mesh.CharacteristicLengthMax = 0.005;\n", "max_dofs"),
    # a transfinite mesh of 1e8 nodes under a small memory limit
    ("settings: {limits: {max_memory_gb: 0.3}}", "Transfinite Curve {1, 2, 3, 4} = 10000;\nTransfinite Surface {1};\n",
     "memory"),
])
def test_hang_and_resource_cases_end_within_the_limit(tmp_path, settings, geo_extra, words):
    scene = _write(tmp_path, BODY + geo_extra, settings)
    t0 = time.monotonic()
    proc = run_cli("validate", str(scene), cwd=tmp_path)
    assert time.monotonic() - t0 < 20
    line = one_error_line(proc, 2 if "max_dofs" in words else 4)
    assert words in line and "system.file" in line


def test_sandbox_alone_stops_a_write(tmp_path, monkeypatch):
    """Past the allowlist (called directly here), Gmsh's own SystemCall runs in the child, but bubblewrap
    leaves it no write access outside the child's folder: the marker stays absent. Without bubblewrap
    the same file does create it (so the test can fail)."""
    from app.systems.gmsh import sandbox as gmsh_sandbox
    from app.systems.schema import Limits
    if not gmsh_sandbox.bwrap_usable():
        pytest.skip("bubblewrap not usable on this machine")
    lim = gmsh_sandbox.SandboxLimits.from_limits(Limits())
    marker = tmp_path / "MARKER"
    (tmp_path / "evil.geo").write_text(BODY + f'SystemCall "touch {marker}";\n')
    gmsh_sandbox.read(tmp_path / "evil.geo", lim)
    assert not marker.exists()
    monkeypatch.setitem(gmsh_sandbox._BWRAP, "usable", False)
    gmsh_sandbox.read(tmp_path / "evil.geo", lim)
    assert marker.exists()


def _msh(tmp_path: pathlib.Path) -> bytes:
    """A small valid MSH 4.1 ASCII mesh of the body (written by Gmsh in this process: trusted)."""
    import gmsh
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    try:
        (tmp_path / "src.geo").write_text(BODY)
        gmsh.open(str(tmp_path / "src.geo"))
        gmsh.model.mesh.generate(2)
        gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
        gmsh.write(str(tmp_path / "src.msh"))
    finally:
        gmsh.finalize()
    return (tmp_path / "src.msh").read_bytes()


def test_msh_header_counts_refused_before_reading(tmp_path):
    """Node tags of 1e15 (a Gmsh segfault) and 1e12 declared nodes: refused from the header."""
    from app.systems.gmsh.mesh import model_info
    from app.systems.schema import SystemPathError
    lines = _msh(tmp_path).decode().splitlines()
    i = lines.index("$Nodes") + 1
    blocks, n, lo, hi = lines[i].split()
    for header, words in ((f"{blocks} {n} {lo} 1000000000000000", "tags up to"),
                          (f"{blocks} 1000000000000 {lo} 1000000000000", "declares")):
        bad = list(lines)
        bad[i] = header
        path = tmp_path / f"h{len(words)}.msh"
        path.write_text("\n".join(bad) + "\n")
        t0 = time.monotonic()
        with pytest.raises(SystemPathError, match=words):
            model_info(path, path.name)
        assert time.monotonic() - t0 < 1.0


def _mutations(src: bytes, count: int, seed: int = 19):
    """``count`` random mutations of ``src``: digits replaced, bytes replaced, the file cut, lines duplicated."""
    rng = random.Random(seed)
    for case in range(count):
        data = bytearray(src)
        kind = case % 4
        for _ in range(rng.randint(1, 4)):
            at = rng.randrange(len(data))
            if kind == 0 and chr(data[at]).isdigit():
                data[at:at + 1] = rng.choice([b"9", b"0", b"-1", b"99999999999", b"1e15", b"."])
            elif kind == 1:
                data[at] = rng.randrange(256)
            elif kind == 2:
                del data[at:]
                break
            else:
                lines = bytes(data).split(b"\n")
                j = rng.randrange(len(lines))
                lines.insert(j, lines[rng.randrange(len(lines))])
                data = bytearray(b"\n".join(lines))
        yield case, bytes(data)


@pytest.mark.slow
def test_mutated_msh_fuzz_never_crashes_this_process(tmp_path):
    """200 random mutations of a valid .msh: each either reads or gives one SystemPathError line;
    Gmsh's crashes stay in its child. (Two files at a time: each child starts Python and Gmsh.)"""
    from concurrent.futures import ThreadPoolExecutor

    from app.systems.gmsh.mesh import _read_uncached
    from app.systems.gmsh.sandbox import SandboxLimits
    from app.systems.schema import Limits, SystemPathError
    lim = SandboxLimits.from_limits(Limits())
    paths = []
    for case, data in _mutations(_msh(tmp_path), 200):
        paths.append(tmp_path / f"fuzz{case}.msh")
        paths[-1].write_bytes(data)

    def one(path: pathlib.Path) -> str:
        try:
            _read_uncached(path, path.name, lim, None)
            return "ok"
        except SystemPathError as err:
            assert err.msg and "\n" not in err.msg
            return "crash" if "crashed" in err.msg else "refused"
    with ThreadPoolExecutor(2) as pool:
        outcomes = list(pool.map(one, paths))
    counts = {k: outcomes.count(k) for k in ("ok", "refused", "crash")}
    assert len(outcomes) == 200 and counts["refused"] + counts["crash"] > 50, counts


def test_contact_curve_inside_the_body_is_refused(tmp_path):
    from app.scene.schema import SceneError, load_scene
    geo = BODY.replace('Physical Curve("AB") = {1};', 'Point(5) = {2, 1, 0, 1}; Point(6) = {8, 1, 0, 1};\n'
                       'Line(5) = {5, 6}; Line{5} In Surface{1};\nPhysical Curve("AB") = {5};\n'
                       'Physical Curve("bottom") = {1};')
    with pytest.raises(SceneError, match=r"system.contact = 'AB': .* inside the body"):
        load_scene(_write(tmp_path, geo))


@pytest.mark.parametrize("example, degree", [("block", 1), ("block", 2), ("l_shape", 1), ("incline", 2)])
def test_validate_sizes_are_the_built_systems_sizes(tmp_path, example, degree):
    """The pre-flight's DOFs and contact nodes of a gmsh scene (from the mesh, no assembly) are those
    of the assembled, Dirichlet-reduced system."""
    import yaml
    from conftest import ROOT
    from mpi4py import MPI

    from app.common.stages import Stages
    from app.scene import limits as preflight
    from app.scene.schema import load_scene
    from app.systems.gmsh import path as gmsh_body
    ex = ROOT / "app" / "scenes" / "gmsh"
    (tmp_path / f"{example}.geo").write_text((ex / f"{example}.geo").read_text())
    data = yaml.safe_load((ex / f"{example}.yaml").read_text())
    data["system"]["degree"] = degree
    (tmp_path / "s.yaml").write_text(yaml.safe_dump(data))
    scene = load_scene(tmp_path / "s.yaml")
    est = preflight.check(scene)
    system = gmsh_body.build(scene.system, MPI.COMM_WORLD, Stages())
    try:
        assert (est.dofs, est.contact_nodes) == (system.n_dofs, len(system.nodes))
    finally:
        system.destroy()


@pytest.mark.parametrize("key, value, words", [
    ("thickness", "true", "a boolean"),
    ("obstacle", "{point: [0, 0], normal: [1.0e+308, -1.0e+308]}", r"less than or equal to 1e\+100"),
    ("obstacle", "{point: [0, 0], normal: [0, -1.0e-320]}", "non-zero vector"),
    ("obstacle", "{point: [1.0e+300, 0], normal: [0, -1]}", r"less than or equal to 1e\+100"),
])
def test_schema_refuses_booleans_and_overflowing_values(tmp_path, key, value, words):
    from app.scene.schema import SceneError, load_scene
    scene = _write(tmp_path, BODY)
    scene.write_text(scene.read_text().replace("  material:", f"  {key}: {value}\n  material:"))
    with pytest.raises(SceneError, match=words):
        load_scene(scene)


@pytest.mark.parametrize("program, words", [
    ("{steps: 1, displacement: {CD: {translation: [0, -0.01], rotation_deg: 1.0e+10}}}", "less than or equal to 3600"),
    ("{steps: 1, displacement: {CD: {translation: [1.0e+300, 0]}}}", r"less than or equal to 1e\+100"),
    ("{steps: 1, displacement: {CD: {translation: [0, -1]}}, until: {normal_force: 1.0e+300}}", r"less than or equal to 1e\+100"),
])
def test_program_values_in_range(tmp_path, program, words):
    from app.scene.schema import SceneError, load_scene
    scene = _write(tmp_path, BODY)
    text = scene.read_text().replace("{steps: 2, displacement: {CD: {translation: [0, -0.01]}}}", program)
    scene.write_text(text)
    with pytest.raises(SceneError, match=words):
        load_scene(scene)


def test_large_motion_of_a_gmsh_body_warns(tmp_path):
    """Small-strain warnings apply to gmsh bodies: a prescribed rotation of 30 degrees."""
    import yaml
    from conftest import run_scene
    _write(tmp_path, BODY)
    data = yaml.safe_load((tmp_path / "scene.yaml").read_text())
    data["system"]["file"] = str(tmp_path / "body.geo")
    data["system"]["program"] = [{"steps": 1, "displacement": {"CD": {"translation": [0, -0.01], "rotation_deg": 30}}}]
    warnings = run_scene(data)["warnings"]
    assert any("linearised rotation" in w for w in warnings), warnings


def test_sandbox_removes_only_its_own_folder(tmp_path, monkeypatch):
    """The child's working folder is one the app made (mkdtemp) and the only thing it removes:
    the scene's folder and a user's folders in the temporary area are left as they were."""
    from app.systems.gmsh import sandbox as gmsh_sandbox
    from app.systems.schema import Limits
    tmpdir = tmp_path / "tmp"
    tmpdir.mkdir()
    (tmpdir / "app-gmsh-users-own").mkdir()               # a user's folder named like the app's
    (tmpdir / "app-gmsh-users-own" / "keep.txt").write_text("mine")
    monkeypatch.setenv("TMPDIR", str(tmpdir))
    import tempfile
    monkeypatch.setattr(tempfile, "tempdir", None)        # tempfile reads TMPDIR again
    scene = tmp_path / "scene"
    scene.mkdir()
    (scene / "body.geo").write_text(BODY)
    (scene / "notes.txt").write_text("mine")
    before = sorted(p.name for p in scene.iterdir())
    gmsh_sandbox.read(scene / "body.geo", gmsh_sandbox.SandboxLimits.from_limits(Limits()))
    assert sorted(p.name for p in scene.iterdir()) == before
    assert sorted(p.name for p in tmpdir.iterdir()) == ["app-gmsh-users-own"]
    assert (tmpdir / "app-gmsh-users-own" / "keep.txt").read_text() == "mine"


def test_jit_parameter_files_in_the_working_folder_are_ignored(tmp_path):
    """DOLFINx and FFCx read ``dolfinx_jit_parameters.json`` and ``ffcx_parameters.json`` from the
    current folder: there they would redirect the compiled code to another folder, add compiler
    flags, or (``tabulate_tensor_void``) compile empty kernels. The app fixes every parameter
    (app/systems/jit.py), so a run from such a folder compiles nothing there and gives the same answer."""
    import json
    evil = tmp_path / "elsewhere"
    scene = _write(tmp_path, BODY)
    p = run_cli("run", str(scene), "-o", str(tmp_path / "clean"), "-q", cwd=tmp_path)
    assert p.returncode == 0, p.stderr
    (tmp_path / "dolfinx_jit_parameters.json").write_text(json.dumps(
        {"cache_dir": str(evil), "cffi_extra_compile_args": ["-O0", "-DINJECTED"], "timeout": 1}))
    (tmp_path / "ffcx_parameters.json").write_text(json.dumps({"tabulate_tensor_void": True, "epsilon": 0.5}))
    p = run_cli("run", str(scene), "-o", str(tmp_path / "out"), "-q", cwd=tmp_path)
    assert p.returncode == 0, p.stdout + p.stderr
    assert not evil.exists()
    got, want = (json.loads((tmp_path / d / "results.json").read_text()) for d in ("out", "clean"))
    assert [s["classification"] for s in got["states"]] == [s["classification"] for s in want["states"]]
    assert [s["u_N"] for s in got["states"][-1]["nodes"]] == [s["u_N"] for s in want["states"][-1]["nodes"]]
