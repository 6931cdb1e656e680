"""The docs in the repository: generated scene-key reference up to date, links inside the
repository, and the literate example run end to end (it asserts the paper's numbers)."""
from __future__ import annotations

import pathlib
import re
import runpy
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]


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
    from app.config import Block, Loading, McpSettings, Scene
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
