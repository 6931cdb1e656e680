"""``python -m app render`` with the user's choices and on a sweep (issue 35): ``--states`` and
``--field`` picture other states or another field than the scene asked for, validated as the
scene's own keys; a sweep's folder redraws every case."""
import json

import yaml
from conftest import run_cli

BLOCK = {"name": "b", "mu": 1.1, "analyses": ["mceip_mu"],
         "system": {"type": "block", "nx": 8, "ny": 4},
         "loading": {"normal_steps": 4, "tangential_step": 0.5, "tangential_max": 4.0},
         "outputs": {"plots": True, "paraview": True, "states": ["final"],
                     "screenshots": {"resolution": [320, 200], "modes": False}}}


def test_render_pictures_other_states_and_another_field(tmp_path):
    (tmp_path / "s.yaml").write_text(yaml.safe_dump(BLOCK))
    out = tmp_path / "out"
    p = run_cli("run", str(tmp_path / "s.yaml"), "-o", str(out), "-q")
    assert p.returncode == 0, p.stderr
    final = json.loads((out / "results.json").read_text())["states"][-1]["index"]
    assert (out / "screenshots" / f"state_{final:04d}_von_mises.png").is_file()
    p = run_cli("render", str(out), "--states", "3", "--states", "final", "--field", "displacement")
    assert p.returncode == 0, p.stderr
    shots = sorted(f.name for f in (out / "screenshots").iterdir())
    assert shots == [f"state_{final:04d}_displacement.png"], shots
    # the run saved the fields of the states it pictured only: state 3 is left out, and said so
    assert "note: screenshot of state 3 left out: its field is not in fields.npz" in p.stderr, p.stderr
    # results.json is left as the run wrote it
    assert json.loads((out / "results.json").read_text())["scene_config"]["outputs"]["states"] == ["final"]
    # a selector the scene could not hold: one line naming the key, nothing redrawn
    p = run_cli("render", str(out), "--states", "latest")
    assert p.returncode == 2 and p.stderr.count("\n") == 1 and "outputs.states" in p.stderr, p.stderr
    assert sorted(f.name for f in (out / "screenshots").iterdir()) == shots


def test_render_a_sweep_redraws_every_case(tmp_path):
    scene = {**BLOCK, "outputs": {"plots": True}, "sweep": {"parameters": {"mu": [0.8, 1.1]}}}
    (tmp_path / "s.yaml").write_text(yaml.safe_dump(scene))
    out = tmp_path / "out"
    p = run_cli("run", str(tmp_path / "s.yaml"), "-o", str(out), "-q")
    assert p.returncode == 0, p.stderr
    plots = sorted(out.glob("cases/*/plots/mceip_mu.png"))
    assert len(plots) == 2
    for f in plots:
        f.unlink()                                  # gone: render must draw them again
    p = run_cli("render", str(out))
    assert p.returncode == 0, p.stderr
    assert all(f.is_file() for f in plots)
    assert p.stdout.count("redrew") == 2


def test_render_a_sweep_never_follows_a_link_among_its_cases(tmp_path):
    """A sweep folder from someone else whose cases/ holds a symbolic link to another results
    folder (a user's own): the link is skipped with one line, nothing is written through it."""
    import os
    import shutil
    scene = {**BLOCK, "outputs": {"plots": True}, "sweep": {"parameters": {"mu": [0.8]}}}
    (tmp_path / "s.yaml").write_text(yaml.safe_dump(scene))
    out = tmp_path / "out"
    p = run_cli("run", str(tmp_path / "s.yaml"), "-o", str(out), "-q")
    assert p.returncode == 0, p.stderr
    (case,) = [d for d in (out / "cases").iterdir() if d.is_dir()]
    mine = tmp_path / "mine"
    shutil.copytree(case, mine)                 # a results folder of the user's, elsewhere
    for f in (mine / "plots").iterdir():
        f.unlink()
    os.symlink(mine, out / "cases" / "linked")
    p = run_cli("render", str(out))
    assert p.returncode == 2
    assert [ln for ln in p.stderr.splitlines() if "linked" in ln] == [
        f"error: {out / 'cases' / 'linked'}: not a case folder this app wrote (skipped)"]
    assert not any((mine / "plots").iterdir())  # nothing drawn through the link
    assert (case / "plots" / "mceip_mu.png").is_file()
