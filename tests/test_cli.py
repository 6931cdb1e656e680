"""The command line and the scene loader against user mistakes.

Every bad scene file must give exit status 2 and ONE line ``error: <file>: <key path> = <value>:
<what is allowed>`` on stderr, never a traceback, and ``run`` must not write results. The valid
two-particle scene must run and write results.json / steps.csv of the documented shape. A
hypothesis fuzz of :func:`app.scene.schema.parse_scene` / :func:`app.scene.schema.load_scene` checks that
nothing but a :class:`~app.scene.schema.Scene` or a one-line :class:`~app.scene.schema.SceneError` comes out.
"""
from __future__ import annotations

import copy
import json
import math
import pathlib
import subprocess
from dataclasses import dataclass

import pytest
import yaml
from conftest import ROOT, run_cli, run_cli_here
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

VALID = """\
name: two-particles
system: {type: two_particles, k: 1000.0, m: 2.0, phi_deg: 35.0, signs: [1, -1]}
mu: 2.5
analyses: [necessary, sufficient, mceip_lambda2, mceip_mu, enumerate]
"""
BLOCK = """\
name: block
system: {type: block, nx: 4, ny: 2, nu: 0.3}
mu: 1.0
loading: {normal_force: 55.0, normal_steps: 2, tangential_step: 0.5, tangential_max: 1.0}
"""
ANALYSES_LINE = "analyses: [necessary, sufficient, mceip_lambda2, mceip_mu, enumerate]"
MISSING, FOLDER = object(), object()     # special "contents": no file at all / a folder


def _laughs(levels: int = 9) -> str:
    """A YAML alias bomb: 9**levels leaves if anything walks it."""
    out = ["l0: &l0 [x, x, x, x, x, x, x, x, x]"]
    for i in range(1, levels):
        out.append(f"l{i}: &l{i} [" + ", ".join([f"*l{i - 1}"] * 9) + "]")
    return "\n".join(out) + "\n"


@dataclass(frozen=True)
class Bad:
    id: str
    contents: object          # str (UTF-8 text), bytes, MISSING or FOLDER
    needles: tuple[str, ...]  # all must appear in the error line


BAD = [
    Bad("unknown_top_key", VALID + "colour: red\n", ("unknown key 'colour'",)),
    Bad("unknown_system_key", VALID.replace("signs:", "stiffness: 3, signs:"), ("unknown key 'system.stiffness'",)),
    Bad("mu_not_a_number", VALID.replace("mu: 2.5", "mu: abc"), ("mu = 'abc'", "number")),
    Bad("mu_negative", VALID.replace("mu: 2.5", "mu: -0.5"), ("mu = -0.5", "greater than or equal to 0")),
    Bad("mu_nan", VALID.replace("mu: 2.5", "mu: .nan"), ("mu = nan", "finite")),
    Bad("phi_zero", VALID.replace("phi_deg: 35.0", "phi_deg: 0"), ("system.phi_deg = 0", "greater than 0")),
    Bad("phi_95", VALID.replace("phi_deg: 35.0", "phi_deg: 95"), ("system.phi_deg = 95", "less than 90")),
    Bad("signs_zero", VALID.replace("[1, -1]", "[1, 0]"), ("system.signs = [1, 0]", "-1 or 1")),
    Bad("signs_two", VALID.replace("[1, -1]", "[2, -1]"), ("system.signs = [2, -1]", "-1 or 1")),
    Bad("signs_length_3", VALID.replace("[1, -1]", "[1, -1, 1]"), ("system.signs = [1, -1, 1]", "two signs")),
    Bad("signs_floats", VALID.replace("[1, -1]", "[1.0, -1.0]"), ("system.signs = [1.0, -1.0]", "integer")),
    Bad("signs_bools", VALID.replace("[1, -1]", "[true, false]"), ("system.signs = [True, False]", "integer")),
    Bad("unknown_system_type", VALID.replace("type: two_particles", "type: three_particles"),
        ("system.type = 'three_particles'", "'two_particles', 'block'")),
    Bad("missing_system_type", VALID.replace("type: two_particles, ", ""),
        ("missing key 'system.type'", "'two_particles', 'block'")),
    Bad("system_not_a_mapping", "name: a\nsystem: [1, 2]\nmu: 1\n", ("system = [1, 2]", "mapping")),
    Bad("missing_mu", VALID.replace("mu: 2.5\n", ""), ("missing key 'mu'",)),
    Bad("analyses_unknown", VALID.replace("enumerate]", "eigen]"), ("analyses.4 = 'eigen'", "'necessary'")),
    Bad("analyses_duplicate", VALID.replace("enumerate]", "enumerate, necessary]"),
        ("analyses = [", "listed twice: necessary")),
    Bad("loading_for_two_particles", VALID + "loading: {normal_steps: 3}\n",
        ("loading = {", "'normal_steps': 3", "two_particles", "remove 'loading'")),
    Bad("block_nu_half", BLOCK.replace("nu: 0.3", "nu: 0.5"), ("system.nu = 0.5", "needs element: mixed")),
    Bad("block_nu_above_half", BLOCK.replace("nu: 0.3", "nu: 0.51"), ("system.nu = 0.51", "less than or equal to 0.5")),
    Bad("block_nx_zero", BLOCK.replace("nx: 4", "nx: 0"), ("system.nx = 0", "greater than or equal to 1")),
    Bad("block_unstructured_without_mesh_size", BLOCK.replace("nu: 0.3", "nu: 0.3, pattern: unstructured"),
        ("system.mesh_size = None", "mesh_size")),
    Bad("normal_steps_zero", BLOCK.replace("normal_steps: 2", "normal_steps: 0"),
        ("loading.normal_steps = 0", "greater than or equal to 1")),
    Bad("yaml_unbalanced_bracket", VALID.replace("[1, -1]", "[1, -1"), ("invalid YAML", "line 2, column")),
    Bad("yaml_bad_tag", VALID.replace("mu: 2.5", "mu: !!int abc"), ("invalid YAML", "could not be converted")),
    Bad("yaml_too_deep", "[" * 3000 + "]" * 3000, ("invalid YAML", "nested too deeply")),
    Bad("yaml_alias_bomb", VALID.replace("mu: 2.5\n", "") + _laughs() + "mu: *l8\n", ("mu = [[", "valid number")),
    Bad("top_level_list", "- name: a\n- mu: 1\n", ("(top level) = [", "mapping", "not a list")),
    Bad("top_level_scalar", "just a string\n", ("(top level) = 'just a string'", "mapping")),
    Bad("key_not_a_string", VALID + "1: 2\n", ("key 1", "strings")),
    Bad("empty_file", "", ("empty", "name, system, mu")),
    Bad("missing_file", MISSING, ("no such scene file",)),
    Bad("folder_not_file", FOLDER, ("folder",)),
    Bad("not_utf8", VALID.replace("two-particles", "caf\u00e9").encode("latin-1"), ("not UTF-8", "0xe9")),
    Bad("name_with_slash", VALID.replace("name: two-particles", "name: a/b"), ("name = 'a/b'", "letters, digits")),
    Bad("name_with_space", VALID.replace("name: two-particles", "name: my scene"),
        ("name = 'my scene'", "no spaces or slashes")),
    Bad("name_dots", VALID.replace("name: two-particles", "name: '..'"), ("name = '..'", "letters, digits")),
]
RUN_SUBSET = {"unknown_top_key", "phi_95", "loading_for_two_particles", "yaml_unbalanced_bracket",
              "missing_file", "not_utf8"}
assert len({b.id for b in BAD}) == len(BAD) and RUN_SUBSET <= {b.id for b in BAD}


def _materialise(root: pathlib.Path, bad: Bad) -> pathlib.Path:
    path = root / f"{bad.id}.yaml"
    if bad.contents is FOLDER:
        path.mkdir()
    elif isinstance(bad.contents, bytes):
        path.write_bytes(bad.contents)
    elif isinstance(bad.contents, str):
        path.write_text(bad.contents, encoding="utf-8")
    return path


@pytest.fixture(scope="module")
def bad_outcomes(tmp_path_factory):
    """All CLI calls of the bad-scene matrix, in this process (each would be a ~1 s interpreter start)."""
    root = tmp_path_factory.mktemp("bad")
    jobs = {}
    for bad in BAD:
        path = _materialise(root, bad)
        jobs[bad.id, "validate"] = (path, None, ("validate", str(path)))
        if bad.id in RUN_SUBSET:
            out = root / f"out-{bad.id}"
            jobs[bad.id, "run"] = (path, out, ("run", str(path), "-o", str(out), "-q"))
    return {key: (path, out, run_cli_here(*args)) for key, (path, out, args) in jobs.items()}


def assert_one_line_error(proc: subprocess.CompletedProcess, *needles: str) -> str:
    """Exit status 2, no traceback, stdout empty, stderr exactly one line ``error: ...`` containing needles."""
    assert "Traceback" not in proc.stdout + proc.stderr, proc.stderr
    assert proc.returncode == 2, (proc.returncode, proc.stdout, proc.stderr)
    lines = proc.stderr.splitlines()
    assert len(lines) == 1, proc.stderr
    line = lines[0]
    assert line.startswith("error: ") and line[len("error: "):].strip(), line
    for needle in needles:
        assert needle in line, f"{needle!r} not in {line!r}"
    assert len(line) < 400, line
    return line


@pytest.mark.parametrize("bad", BAD, ids=[b.id for b in BAD])
def test_validate_rejects_bad_scene(bad, bad_outcomes):
    path, _, proc = bad_outcomes[bad.id, "validate"]
    line = assert_one_line_error(proc, str(path), *bad.needles)
    assert line.startswith(f"error: {path}: "), line
    assert proc.stdout == ""


@pytest.mark.parametrize("bad", [b for b in BAD if b.id in RUN_SUBSET], ids=sorted(RUN_SUBSET, key=[b.id for b in BAD].index))
def test_run_rejects_bad_scene(bad, bad_outcomes):
    path, out, proc = bad_outcomes[bad.id, "run"]
    assert_one_line_error(proc, str(path), *bad.needles)
    assert not (out / "results.json").exists()
    assert not (out / "steps.csv").exists()


@pytest.mark.parametrize("kind", ["under_a_file", "under_proc", "is_a_file"])
def test_run_output_folder_cannot_be_created(kind, scene_file, tmp_path):
    scene = scene_file(VALID)
    blocker = tmp_path / "a_file"
    blocker.write_text("not a folder\n")
    out = {"under_a_file": blocker / "x", "under_proc": pathlib.Path("/proc/forbidden/x"),
           "is_a_file": blocker}[kind]
    proc = run_cli_here("run", str(scene), "-o", str(out), "-q")
    line = assert_one_line_error(proc, str(out), "output folder")
    assert "cannot create" in line
    assert not (tmp_path / "results.json").exists()


# --- help, validate ok, console script --------------------------------------------------------

@pytest.mark.parametrize("args", [("--help",), ("run", "--help")], ids=["top", "run"])
def test_help(args):
    proc = run_cli(*args, timeout=60)
    assert proc.returncode == 0, proc.stderr
    text = proc.stdout
    assert "run" in text and "validate" in text
    assert "Units:" in text and "mm" in text and "MPa" in text
    assert "Traceback" not in proc.stdout + proc.stderr


def test_no_command_prints_help_and_exits_2():
    proc = run_cli_here()
    assert proc.returncode == 2
    assert "usage:" in proc.stdout + proc.stderr
    assert "validate" in proc.stdout + proc.stderr
    assert "Traceback" not in proc.stdout + proc.stderr


def test_console_script_help():
    exe = ROOT / ".venv" / "bin" / "contact-divergence"
    if not exe.exists():
        pytest.skip("console script not installed (pip install -e .)")
    proc = subprocess.run([str(exe), "--help"], capture_output=True, text=True, timeout=60, cwd=ROOT)
    assert proc.returncode == 0, proc.stderr
    assert "validate" in proc.stdout and "Units:" in proc.stdout


def test_validate_ok(scene_file):
    path = scene_file(VALID)
    proc = run_cli_here("validate", str(path))
    assert proc.returncode == 0, proc.stderr
    assert "ok" in proc.stdout and "two-particles" in proc.stdout
    assert proc.stderr == ""


# --- a real run -------------------------------------------------------------------------------

def _check_solution(sol: dict, n: int) -> None:
    assert math.isfinite(sol["value"]) and sol["value"] >= 0
    assert len(sol["x_Ts"]) == n and min(sol["x_Ts"]) >= -1e-12
    assert sum(sol["x_Ts"]) == pytest.approx(1.0, abs=1e-9)
    assert len(sol["pattern"]) == n and set(sol["pattern"]) <= {"slip", "stick"}


def test_run_two_particles_writes_results(scene_file, tmp_path):
    out = tmp_path / "out"
    proc = run_cli_here("run", str(scene_file(VALID)), "-o", str(out), "-q")
    assert proc.returncode == 0, proc.stderr
    assert "Traceback" not in proc.stdout + proc.stderr
    assert (out / "results.json").is_file() and (out / "steps.csv").is_file()
    res = json.loads((out / "results.json").read_text())
    assert res["scene"] == "two-particles"
    assert res["units"]["length"] == "mm" and res["units"]["lambda2"] == "1/s^2"
    assert res["stages"] and all(isinstance(s["name"], str) and s["seconds"] >= 0 for s in res["stages"])
    assert res["failures"] == []
    (state,) = res["states"]
    assert len(state["nodes"]) == 2
    for i, node in enumerate(state["nodes"]):
        assert {"id", "x", "status", "sign", "r_N", "r_T"} <= node.keys()
        assert node["id"] == i and node["status"] == "slip"
    assert [n["sign"] for n in state["nodes"]] == [1, -1]
    an = state["analyses"]
    assert {"necessary", "sufficient", "mceip_mu", "mceip_lambda2", "enumerate"} <= an.keys()
    assert isinstance(an["necessary"]["satisfied"], bool)
    assert isinstance(an["sufficient"]["satisfied"], bool)
    assert an["mceip_mu"]["solutions"], "MCEIP-mu has solutions for this system (Table 1)"
    for key in ("mceip_mu", "mceip_lambda2", "enumerate"):
        for sol in an[key]["solutions"]:
            _check_solution(sol, 2)
    rows = (out / "steps.csv").read_text().splitlines()
    assert rows[0].startswith("index,") and len(rows) == 2


# --- fuzz of the loader (in process) ----------------------------------------------------------

from app.scene.schema import Scene, SceneError, load_scene, parse_scene  # noqa: E402

BASES = [yaml.safe_load(VALID), yaml.safe_load(BLOCK)]
KEYS = ["name", "system", "mu", "analyses", "mceip_lambda2_mu", "loading", "settings", "type", "k", "m",
        "phi_deg", "signs", "length", "height", "thickness", "nx", "ny", "pattern", "mesh_size", "degree",
        "plane", "E", "nu", "density", "mass", "normal_force", "normal_steps", "tangential_step",
        "tangential_max", "mcp", "eig", "classify_rtol", "enumerate_max_slip", "enumerate_problems",
        "mceip_mu_method", "starts", "rtol", "max_it", "nev", "tol", "dense_limit"]
WORDS = ["two_particles", "block", "unstructured", "crossed", "necessary", "sufficient", "mceip_mu",
         "mceip_lambda2", "enumerate", "stress", "strain", "lumped", "mu", "lambda2", "condensed", "a/b", ""]
text = st.text(alphabet=st.characters(exclude_categories=("Cs",)), max_size=20)
scalars = st.one_of(
    st.none(), st.booleans(), st.integers(), st.integers(-3, 3),
    st.floats(allow_nan=True, allow_infinity=True), st.sampled_from([0, 0.5, 1, -1, 2, 35.0, 89.9, 90, 95, 1e300]),
    text, st.sampled_from(WORDS + KEYS))
keys = st.one_of(st.sampled_from(KEYS), text, st.integers(-2, 2), st.none(), st.booleans())
junk = st.recursive(scalars, lambda kids: st.one_of(st.lists(kids, max_size=4),
                                                    st.dictionaries(keys, kids, max_size=4)), max_leaves=12)


def _containers(obj, out):
    if isinstance(obj, (dict, list)):
        out.append(obj)
        for v in (obj.values() if isinstance(obj, dict) else obj):
            _containers(v, out)
    return out


@st.composite
def mutated_scene(draw):
    """The valid scene (or the block scene) after 0-5 random deletions, replacements and additions."""
    doc = copy.deepcopy(draw(st.sampled_from(BASES)))
    for _ in range(draw(st.integers(0, 5))):
        target = draw(st.sampled_from(_containers(doc, [])))
        op = draw(st.sampled_from(["delete", "replace", "add"]))
        if isinstance(target, dict):
            if op == "add" or not target:
                target[draw(keys)] = draw(junk)
            else:
                key = draw(st.sampled_from(list(target)))
                if op == "delete":
                    del target[key]
                else:
                    target[key] = draw(junk)
        else:
            if op == "add" or not target:
                target.insert(draw(st.integers(0, len(target))), draw(junk))
            else:
                i = draw(st.integers(0, len(target) - 1))
                if op == "delete":
                    del target[i]
                else:
                    target[i] = draw(junk)
    if draw(st.integers(0, 19)) == 0:
        doc = draw(junk)                       # a top level that is not the scene at all
    return doc


SNIPPETS = ["[", "]", "{", "}", ":", ": ", "- ", "\t", "\n", "  ", "'", '"', "&a ", "*a", "*zz", "!!int abc",
            "!!timestamp x", "!!binary '@'", "!!float x", "!!python/object:os.system x", "? [1, 2]\n: 3\n",
            "<<: 3\n", "<<: {a: 1}\n", "---\n", "...\n", "%YAML 1.1\n", "1" * 5000, "[" * 1500, "&r [*r]",
            "\u2028", "\x85", "\x00", "\ufeff", "#", "|\n", ">-\n", "mu: .nan\n", "mu: 1e999\n"]


@st.composite
def scene_text(draw):
    """Text of a scene: a dumped mutated scene or the valid text, with random snippets spliced in."""
    kind = draw(st.sampled_from(["dump", "splice", "value", "random"]))
    if kind == "random":
        return draw(st.text(alphabet=st.characters(exclude_categories=("Cs",)), max_size=200))
    if kind == "value":                        # a top-level value replaced by a snippet or junk text
        lines = draw(st.sampled_from([VALID, BLOCK])).splitlines()
        i = draw(st.integers(0, len(lines) - 1))
        key = lines[i].split(":", 1)[0]
        lines[i] = f"{key}: {draw(st.one_of(st.sampled_from(SNIPPETS), text))}"
        return "\n".join(lines) + "\n"
    if kind == "dump":
        base = yaml.safe_dump(draw(mutated_scene()), allow_unicode=draw(st.booleans()))
    else:
        base = draw(st.sampled_from([VALID, BLOCK]))
    for _ in range(draw(st.integers(0, 4))):
        i = draw(st.integers(0, len(base)))
        if draw(st.booleans()):
            base = base[:i] + draw(st.one_of(st.sampled_from(SNIPPETS), text)) + base[i:]
        else:
            base = base[:i] + base[i + draw(st.integers(1, 10)):]
    return base


def _check_outcome(call) -> None:
    try:
        result = call()
    except SceneError as err:
        msg = str(err)
        assert msg.strip() and len(msg.splitlines()) == 1, repr(msg)
        assert len(msg) < 1000, msg
    else:
        assert isinstance(result, Scene)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(doc=mutated_scene())
def test_fuzz_parse_scene(doc):
    _check_outcome(lambda: parse_scene(doc, "fuzz.yaml"))


@pytest.fixture(scope="module")
def fuzz_dir(tmp_path_factory):
    return tmp_path_factory.mktemp("fuzz")


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(body=st.one_of(scene_text(), st.binary(max_size=200)))
def test_fuzz_load_scene(body, fuzz_dir):
    path = fuzz_dir / "scene.yaml"
    if isinstance(body, bytes):
        path.write_bytes(body)
    else:
        path.write_text(body, encoding="utf-8")
    _check_outcome(lambda: load_scene(path))


def test_fuzz_seeds_are_meaningful():
    """The unmutated bases are valid, so the fuzz explores around real scenes."""
    for base in BASES:
        assert isinstance(parse_scene(copy.deepcopy(base)), Scene)


def test_the_top_level_help_names_every_system_type():
    """``python -m app --help`` lists every registered system type (it named only the block and the
    two particles while Gmsh bodies and matrix files were the users' own problems)."""
    from app.cli.main import _parser
    from app.systems import SYSTEM_TYPES
    text = _parser().format_help()
    assert all(f"\n  {name} " in text for name in SYSTEM_TYPES), text
