"""The docs in the repository: the MkDocs site builds with no warning (dead links between pages
and missing anchors are warnings), the generated pages (scene keys, command line) are up to
date, README's and CHANGELOG's links resolve, the method page's newcomer trace names what the
default run really calls, and the literate example runs end to end (it asserts the paper's
numbers)."""
from __future__ import annotations

import os
import pathlib
import re
import runpy
import subprocess
import sys
import unicodedata

import pytest
from mpi4py import MPI

ROOT = pathlib.Path(__file__).resolve().parents[1]
DOCS = [ROOT / "README.md", ROOT / "CHANGELOG.md", *sorted((ROOT / "docs").glob("*.md"))]


def _scene_keys():
    sys.path.insert(0, str(ROOT / "scripts"))
    try:
        import scene_keys
    finally:
        sys.path.pop(0)
    return scene_keys


def test_scene_keys_reference_is_generated_from_the_schema():
    """docs/scene-keys.md is the output of scripts/scene_keys.py (regenerate: run that script)."""
    gen = _scene_keys()
    text = gen.generate()
    assert (ROOT / "docs" / "scene-keys.md").read_text(encoding="utf-8") == text, \
        "docs/scene-keys.md is stale: run .venv/bin/python scripts/scene_keys.py"
    from app.scene.schema import Block, Loading, McpSettings, Scene
    for model in (Scene, Block, Loading, McpSettings):        # every key is listed
        for key in model.model_fields:
            assert f"| `{key}` |" in text, key
    assert "| `nx` | integer (>= 1, <= 4096) | `20` |" in text
    assert "| `mu` | number (>= 0, <= 1e+100) | **required** |" in text   # every number bounded (issue 19)


@pytest.mark.parametrize("doc", DOCS, ids=lambda p: p.name)
def test_docs_stay_inside_the_repository(doc):
    text = doc.read_text(encoding="utf-8")
    assert "../shared" not in text and "shared/DESIGN" not in text   # a clone has no ../shared
    for target in re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", text):
        if re.match(r"[a-z]+://", target):
            continue
        path = (doc.parent / target).resolve()
        assert path.exists(), f"{doc.name}: link to {target} (no such file)"
        assert ROOT in path.parents or path == ROOT, f"{doc.name}: link {target} leaves the repository"


def _slug(heading: str) -> str:
    """Python-Markdown's toc anchor of a heading (the one MkDocs links to)."""
    text = re.sub(r"<[^>]+>|`", "", heading)
    text = unicodedata.normalize("NFKD", text).encode("ascii", "ignore").decode()
    text = re.sub(r"[^\w\s-]", "", text).strip().lower()
    return re.sub(r"[-\s]+", "-", text)


def _anchors(path: pathlib.Path) -> set[str]:
    text = re.sub(r"```.*?```", "", path.read_text(encoding="utf-8"), flags=re.S)
    return {_slug(h) for h in re.findall(r"^#+ (.+?)\s*$", text, re.M)}


@pytest.mark.parametrize("doc", [ROOT / "README.md", ROOT / "CHANGELOG.md"], ids=lambda p: p.name)
def test_links_outside_the_site_resolve_with_their_anchors(doc):
    """README.md and CHANGELOG.md are not pages of the site: their links (and anchors) are checked here."""
    for target, anchor in re.findall(r"\]\(([^)#\s]+)(?:#([^)]*))?\)", doc.read_text(encoding="utf-8")):
        if re.match(r"[a-z]+://", target):
            continue
        path = (doc.parent / target).resolve()
        assert path.exists(), f"{doc.name}: dead link {target}"
        if anchor:
            assert anchor in _anchors(path), f"{doc.name}: {target} has no anchor #{anchor}"


def test_readme_is_a_front_page():
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    assert len(text.splitlines()) <= 200
    first_screen = "\n".join(text.splitlines()[:40])
    assert "divergence instabilities" in first_screen.lower()
    for part in ("Pinto da Costa", "Martins", "Complementarity: Applications, Algorithms and Extensions", "2001"):
        assert part in first_screen, part
    assert "make run" in text and "make test" in text and "make lock" in text
    summary = re.search(r"```text\n(scene 'villechaise-block'.*?)```", text, re.S)
    assert summary and "MCEIP-mu: 1.7048" in summary.group(1)
    # the summary shown is the one the default study prints (up to its timings and folders)
    from app.io.summary import summary as printed
    from app.scene.schema import Outputs, load_scene
    from app.study.run import study
    scene = load_scene(ROOT / "app" / "scenes" / "villechaise_block.yaml")
    res = study(scene.model_copy(update={"outputs": Outputs()}), MPI.COMM_WORLD)      # no files or pictures
    shown = summary.group(1).split("\n  wall time")[0].splitlines()
    assert shown == printed(res, pathlib.Path("output/villechaise-block")).split("\n  wall time")[0].splitlines()
    assert not (ROOT / "NOTES.md").exists()       # replaced by CHANGELOG.md and docs/limitations.md


def test_site_builds_without_warnings(tmp_path):
    """``mkdocs build --strict`` (as ``make docs``): every page, the generated API reference,
    links between pages and their anchors; a warning fails the build."""
    proc = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(tmp_path / "site")],
                          cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "WARNING" not in proc.stdout + proc.stderr, proc.stderr
    site = tmp_path / "site"
    nav = re.findall(r"^  - [^:]+: (\S+\.md)$", (ROOT / "mkdocs.yml").read_text(), re.M)
    pages = {p.name for p in (ROOT / "docs").glob("*.md")}
    assert set(nav) == pages, set(nav) ^ pages                # every page is in the navigation
    api = (site / "api" / "index.html").read_text(encoding="utf-8")
    assert "first_instability" in api and "load_scene" in api  # mkdocstrings rendered the docstrings


def test_cli_reference_is_generated_from_argparse():
    """docs/cli.md is the output of scripts/cli_reference.py (regenerate: run that script)."""
    sys.path.insert(0, str(ROOT / "scripts"))
    try:
        import cli_reference
    finally:
        sys.path.pop(0)
    columns = os.environ.get("COLUMNS")
    try:
        text = cli_reference.generate()
    finally:
        if columns is None:
            os.environ.pop("COLUMNS", None)
        else:
            os.environ["COLUMNS"] = columns
    assert (ROOT / "docs" / "cli.md").read_text(encoding="utf-8") == text, \
        "docs/cli.md is stale: run .venv/bin/python scripts/cli_reference.py"
    for command in ("run", "render", "validate", "check"):
        assert f"## python -m app {command}" in text
    assert "--ranks-per-case" in text and "cd_necessary_" in text


@pytest.mark.slow
def test_method_trace_names_what_the_default_run_calls(tmp_path, capsys):
    """Every ``app/...py`` — ``function`` step of docs/method.md's newcomer trace is called by
    ``python -m app run`` on the default scene (pictures off), and every module the trace names
    is visited; the modules doing the work of the final MCEIP-mu are named."""
    import yaml
    text = (ROOT / "docs" / "method.md").read_text(encoding="utf-8")
    trace = text[text.index("**A newcomer's trace"):text.index("**results.json**")]
    steps = re.findall(r"^\d+\. `(app/[\w/]+\.py)` — `(\w+)`", trace, re.M)
    named = set(re.findall(r"`(app/[\w/]+\.py)`", trace))
    assert len(steps) >= 6
    for module in ("app/analyses/mceip_mu/state.py", "app/analyses/mceip_mu/candidates.py", "app/analyses/mceip_mu/prover/claims.py",
                   "app/analyses/mceip_mu/kernel/checker.py", "app/analyses/runner.py", "app/loading/contact.py"):
        assert module in named, module
    scene = yaml.safe_load((ROOT / "app" / "scenes" / "villechaise_block.yaml").read_text())
    scene.pop("outputs", None)
    path = tmp_path / "scene.yaml"
    path.write_text(yaml.safe_dump(scene))
    called: set[tuple[str, str]] = set()
    root = str(ROOT) + os.sep

    def profile(frame, event, arg):
        if event == "call" and frame.f_code.co_filename.startswith(root):
            called.add((frame.f_code.co_filename[len(root):], frame.f_code.co_name))
    from app.cli.main import main
    sys.setprofile(profile)
    try:
        status = main(["run", str(path), "-o", str(tmp_path / "out")])
    finally:
        sys.setprofile(None)
    assert status == 0
    assert "MCEIP-mu: 1.7048" in capsys.readouterr().out
    visited = {m for m, _ in called}
    for module, function in steps:
        assert (module, function) in called, f"docs/method.md: {module} {function} is not called by the default run"
    for module in named:
        assert module in visited, f"docs/method.md names {module}, which the default run does not visit"


def test_block_figure_names_the_points_and_axes():
    """docs/block.svg is docs/block_figure.py's output and labels A, B, C, D, the axes and T, N."""
    svg = (ROOT / "docs" / "block.svg").read_text(encoding="utf-8")
    assert svg == runpy.run_path(str(ROOT / "docs" / "block_figure.py"))["svg"](), \
        "docs/block.svg is stale: run .venv/bin/python docs/block_figure.py"
    for label in (">A<", ">B<", ">C<", ">D<", ">x<", ">y<", ">T<", ">N<"):
        assert label in svg, label


@pytest.mark.slow
def test_paper_block_example_runs(capsys):
    """examples/paper_block.py asserts the paper's numbers (1.7048 at the final state, 60.81 at
    2 stick / 15 slip / 4 free, the first solution at 11 slip nodes, lambda^2 > 0 at mu = 2)."""
    runpy.run_path(str(ROOT / "examples" / "paper_block.py"), run_name="__main__")
    out = capsys.readouterr().out
    assert "critical mu: 1.7048" in out


def test_every_thumbnail_is_shown_and_every_shown_one_exists():
    """docs/img/ holds the thumbnails of docs/outputs.md (scripts/doc_thumbnails.py): each one is
    shown there, and each one shown is there."""
    import re
    text = (ROOT / "docs" / "outputs.md").read_text()
    shown = set(re.findall(r"\]\((img/[^)]+\.png)\)", text))
    present = {f"img/{p.name}" for p in (ROOT / "docs" / "img").glob("*.png")}
    assert shown and shown == present, (shown ^ present)
