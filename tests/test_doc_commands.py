"""Every command the README and docs/ show in their code blocks runs as shown (issue 34), on the
files its placeholders stand for: ``scene.yaml``, ``my_scene.yaml`` (a scene of the user's), the
results folder of ``make run``, a sweep. Commands that take minutes are listed in
:data:`TOO_LONG` with their cost; a command that is neither run nor listed fails the test."""
from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys

import pytest
from conftest import ROOT

#: shown commands not run here, and why (each one still has to be shown as written)
TOO_LONG = {
    "python -m app run app/scenes/refinement.yaml": "the refinement study: 20 levels, about 70 s",
    "mpirun -n 4 python -m app run sweep.yaml --ranks-per-case 2": "4 ranks on the 2-core CI machine",
}
APP = re.compile(r"^(?:\.venv/bin/)?python3? -m app\b|^mpirun -n \d+ (?:\.venv/bin/)?python3? -m app\b")


def _shown() -> list[tuple[str, str]]:
    """``(page, command)`` of every ``python -m app`` command in a fenced or indented code block,
    its trailing comment removed."""
    out = []
    for page in [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]:
        text = page.read_text(encoding="utf-8")
        blocks = [m.group(1) for m in re.finditer(r"```\w*\n(.*?)```", text, re.S)]
        blocks += [m.group(1) for m in re.finditer(r"^    (\S.*)$", text, re.M)]
        for block in blocks:
            for line in block.splitlines():
                cmd = re.sub(r"\s+#.*$", "", line.strip())
                if APP.match(cmd):
                    out.append((page.name, cmd))
    return sorted(set(out))


def _normalised(cmd: str) -> str:
    return re.sub(r"(?:\.venv/bin/)?python3? -m app", "python -m app", cmd)


@pytest.fixture(scope="module")
def prepared(tmp_path_factory):
    """The placeholders of the docs: ``scene.yaml`` and ``my_scene.yaml`` (the paper's scene,
    pictures off), ``sweep.yaml`` (a two-case mu sweep) and a results folder of ``make run``
    (pictures on)."""
    import yaml
    d = tmp_path_factory.mktemp("docs")
    scene = yaml.safe_load((ROOT / "app" / "scenes" / "villechaise_block.yaml").read_text())
    scene.pop("outputs", None)
    for name in ("scene.yaml", "my_scene.yaml"):
        (d / name).write_text(yaml.safe_dump(scene))
    (d / "sweep.yaml").write_text(yaml.safe_dump(dict(scene, sweep={"parameters": {"mu": [0.9, 1.1]}}, analyses=["mceip_mu"])))
    proc = _run(f"python -m app run {ROOT / 'app' / 'scenes' / 'villechaise_block.yaml'} -o {d / 'results'} -q", d)
    assert proc.returncode == 0, proc.stderr
    return d


def _workdir(prepared, tmp_path, cmd: str):
    """A fresh folder for one command: the placeholder files, ``app`` (the shipped scenes are
    named ``app/scenes/...``) and, where the command reads a results folder, a copy of it."""
    import shutil
    for name in ("scene.yaml", "my_scene.yaml", "sweep.yaml"):
        shutil.copy(prepared / name, tmp_path / name)
    (tmp_path / "app").symlink_to(ROOT / "app")
    args = shlex.split(cmd)
    if len(args) > 4 and args[3] in ("render", "check", "export"):
        shutil.copytree(prepared / "results", tmp_path / args[4])
    return tmp_path


def _run(cmd: str, cwd) -> subprocess.CompletedProcess:
    args = shlex.split(_normalised(cmd))
    if args[0] == "mpirun":
        args = [args[0], "--oversubscribe", *args[1:]]
    args = [sys.executable if a == "python" else a for a in args]
    env = dict(os.environ, PYTHONPATH=str(ROOT), OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    return subprocess.run(args, cwd=cwd, env=env, capture_output=True, text=True, timeout=300)


def test_every_shown_command_is_run_or_listed():
    """The docs show app commands, and each is either run below or listed with its cost."""
    shown = {_normalised(c) for _, c in _shown()}
    assert len(shown) >= 8
    assert set(TOO_LONG) <= shown, set(TOO_LONG) - shown        # nothing listed that is no longer shown


@pytest.mark.parametrize("page, cmd", _shown())
def test_shown_command_runs(page, cmd, prepared, tmp_path):
    if _normalised(cmd) in TOO_LONG:
        pytest.skip(f"{TOO_LONG[_normalised(cmd)]} (shown in {page})")
    proc = _run(cmd, _workdir(prepared, tmp_path, _normalised(cmd)))
    assert proc.returncode == 0, f"{page}: {cmd}\n{proc.stderr[-2000:]}"
