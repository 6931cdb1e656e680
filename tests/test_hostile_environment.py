"""Odd environments (issue 32): hard resource limits of a batch job, unusable cache and home
folders, output paths with a newline, a Ctrl-C of an mpirun sweep, a full disk under the
drawing processes. Each ends in a result or in one ``error:`` line, never a traceback.
"""
from __future__ import annotations

import os
import pathlib
import resource
import subprocess

from conftest import PY, ROOT

GEO_SCENE = """\
name: g
system:
  type: gmsh
  file: block.geo
  contact: AB
  prescribed: {CD: xy}
  material: {E: 5.0, nu: 0.48, density: 1.2e-9}
  thickness: 9.6
  obstacle: {point: [0, 0], normal: [0, -1]}
  program:
    - {name: press, steps: 10, displacement: {CD: {translation: [0, -1]}}, until: {normal_force: 55}}
    - {name: drag, steps: 10, displacement: {CD: {translation: [-0.5, 0]}}}
mu: 1.1
analyses: [mceip_mu]
"""
BLOCK = """\
name: blk
system: {type: block, nx: 6, ny: 3}
mu: 1.1
loading: {normal_force: 55.0, normal_steps: 3, tangential_step: 0.25, tangential_max: 1.5}
analyses: [mceip_mu]
"""


def _env(**extra: str) -> dict:
    env = dict(os.environ, PYTHONPATH=str(ROOT), OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    env.update(extra)
    return env


def _geo_scene(folder: pathlib.Path) -> pathlib.Path:
    """The shipped .geo block, 10 x 5 cells, with a short loading program."""
    geo = (ROOT / "app" / "scenes" / "gmsh" / "block.geo").read_text()
    (folder / "block.geo").write_text(geo.replace("nx = 20; ny = 10;", "nx = 10; ny = 5;"))
    scene = folder / "g.yaml"
    scene.write_text(GEO_SCENE)
    return scene


# ---------------------------------------------------------------------------------------------
# Hard resource limits (ulimit -v, ulimit -f in a batch job)


def test_child_limits_never_exceed_the_inherited_hard_limits():
    from app.common.rlimits import INFINITY, Limit, lowered, within_inherited
    assert lowered(Limit(10, 10), Limit(INFINITY, INFINITY)) == Limit(10, 10)
    assert lowered(Limit(10, 10), Limit(4, 6)) == Limit(4, 6)              # the soft limit is kept too
    assert lowered(Limit(10, 10), Limit(INFINITY, 6)) == Limit(6, 6)
    assert lowered(Limit(5, 6), Limit(8, 7)) == Limit(5, 6)
    assert lowered(Limit(INFINITY, INFINITY), Limit(3, 9)) == Limit(3, 9)
    assert lowered(Limit(0, 0), Limit(4, 4)) == Limit(0, 0)
    inherited = {resource.RLIMIT_AS: (8 << 30, 8 << 30), resource.RLIMIT_CPU: (INFINITY, INFINITY),
                 resource.RLIMIT_FSIZE: (INFINITY, 1 << 20)}
    got, notes = within_inherited({resource.RLIMIT_AS: Limit(20 << 30, 20 << 30),
                                   resource.RLIMIT_CPU: Limit(62, 63),
                                   resource.RLIMIT_FSIZE: Limit(64 << 20, 64 << 20)}, inherited.__getitem__)
    assert got == {resource.RLIMIT_AS: Limit(8 << 30, 8 << 30), resource.RLIMIT_CPU: Limit(62, 63),
                   resource.RLIMIT_FSIZE: Limit(1 << 20, 1 << 20)}
    assert len(notes) == 2 and "ulimit -v" in notes[0] and "ulimit -f" in notes[1], notes


def test_sandbox_limits_within_the_inherited_ones():
    """The Gmsh child's limits under a batch job's hard ``ulimit -v`` and ``ulimit -f``."""
    from app.common.rlimits import INFINITY, Limit
    from app.systems.gmsh.sandbox import BASE_ADDRESS_SPACE, SandboxLimits, child_limits
    lim = SandboxLimits(seconds=60.0, memory_bytes=1 << 34, max_nodes=10, max_elements=10, max_dofs=20)
    free = {r: (INFINITY, INFINITY) for r in (resource.RLIMIT_AS, resource.RLIMIT_FSIZE, resource.RLIMIT_CPU,
                                               resource.RLIMIT_CORE)}
    got, notes = child_limits(lim, 64 << 20, free.__getitem__)
    assert got[resource.RLIMIT_AS] == Limit((1 << 34) + BASE_ADDRESS_SPACE, (1 << 34) + BASE_ADDRESS_SPACE)
    assert got[resource.RLIMIT_FSIZE] == Limit(64 << 20, 64 << 20) and got[resource.RLIMIT_CPU] == Limit(62, 63)
    assert got[resource.RLIMIT_CORE] == Limit(0, 0) and notes == []
    batch = dict(free)
    batch[resource.RLIMIT_AS] = (8_000_000 << 10, 8_000_000 << 10)
    batch[resource.RLIMIT_FSIZE] = (INFINITY, 1 << 20)
    got, notes = child_limits(lim, 64 << 20, batch.__getitem__)
    assert got[resource.RLIMIT_AS] == Limit(8_000_000 << 10, 8_000_000 << 10)
    assert got[resource.RLIMIT_FSIZE] == Limit(1 << 20, 1 << 20)
    assert len(notes) == 2, notes


def test_geo_scene_runs_under_hard_batch_limits(tmp_path):
    """``ulimit -v`` and ``ulimit -f`` set hard limits, as a batch job's script does: the Gmsh
    sandbox used to ask for more than them and crash in ``preexec_fn``. Now the .geo scene runs,
    and one warning says the inherited address-space limit is lower than the sandbox's."""
    scene = _geo_scene(tmp_path)
    cmd = f'ulimit -v 8000000 && ulimit -f 10000000 && exec "{PY}" -m app run "{scene}" -o "{tmp_path / "out"}" -q'
    p = subprocess.run(["bash", "-c", cmd], capture_output=True, text=True, env=_env(), cwd=tmp_path, timeout=600)
    assert p.returncode == 0, p.stderr
    assert (tmp_path / "out" / "results.json").is_file()
    lines = p.stderr.splitlines()
    assert len(lines) == 1 and "ulimit -v" in lines[0] and "Traceback" not in p.stderr, p.stderr
