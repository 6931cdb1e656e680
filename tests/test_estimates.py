"""The pre-flight estimates (app/scene/limits.py) against measured runs, and what ``validate`` prints.

The measured figures are serial runs of the paper's block study (``analyses: [mceip_mu]``) by
benchmarks/estimates.py on this project's 2-core machine (peak resident memory; CPU seconds);
the 1M-DOF peak is issue 22's measurement. The estimates must stay within a factor 2 of them.
"""
from __future__ import annotations

import pytest
import yaml
from conftest import run_cli_here

from app.scene.limits import describe_time, estimate, time_estimate
from app.scene.schema import default_scene_path, parse_scene

#: nx, measured peak resident memory (GiB), measured CPU seconds (None: not measured)
MEASURED = [(56, 0.245, 3.7), (112, 0.309, 4.6), (224, 0.483, 8.9), (448, 1.283, 37.3), (708, 2.76, 121.2)]


def _scene(nx: int, analyses=("mceip_mu",)):
    data = yaml.safe_load(default_scene_path().read_text())
    data.pop("outputs", None)
    data["analyses"] = list(analyses)
    data["system"].update(nx=nx, ny=nx // 2)
    return parse_scene(data)


@pytest.mark.parametrize("nx, peak_gib, cpu_s", MEASURED)
def test_estimates_within_a_factor_2_of_measured(nx, peak_gib, cpu_s):
    scene = _scene(nx)
    est = estimate(scene)
    assert 0.5 <= est.memory_bytes / 2**30 / peak_gib <= 2.0
    if cpu_s is not None:
        assert 0.5 <= time_estimate(scene, est) / cpu_s <= 2.0


#: nx, measured wall seconds of the default four analyses (serial, 2026-12-06: docs/performance.md)
MEASURED_ALL = [(40, 3.5), (112, 9.1), (224, 44.4)]


@pytest.mark.parametrize("nx, wall_s", MEASURED_ALL)
def test_estimate_of_the_four_default_analyses(nx, wall_s):
    scene = _scene(nx, analyses=("necessary", "sufficient", "mceip_mu", "mceip_lambda2"))
    assert 0.5 <= time_estimate(scene, estimate(scene)) / wall_s <= 2.0


#: nx, measured wall seconds of the incompressible block (mixed element, nu = 1/2, plane strain,
#: drag to 5 mm) with the sufficient condition and MCEIP-lambda^2 (searched: nothing bounds it),
#: serial, 2026-12-06 (whole process: 936 DOFs 8.2 s without MCEIP-mu; 3,671 DOFs 75 s with it)
MEASURED_INCOMPRESSIBLE = [(10, ("sufficient", "mceip_lambda2"), 8.2),
                           (20, ("sufficient", "mceip_mu", "mceip_lambda2"), 74.7)]


@pytest.mark.parametrize("nx, analyses, wall_s", MEASURED_INCOMPRESSIBLE)
def test_estimate_of_the_incompressible_block(nx, analyses, wall_s):
    data = yaml.safe_load((default_scene_path().parent / "block_incompressible.yaml").read_text())
    data.pop("outputs", None)
    data["analyses"] = list(analyses)
    data["system"].update(nx=nx, ny=nx // 2)
    scene = parse_scene(data)
    assert 0.5 <= time_estimate(scene, estimate(scene)) / wall_s <= 2.0


def test_time_estimate_says_what_it_does_not_count():
    scene = _scene(40, analyses=("necessary", "mceip_mu", "enumerate"))
    text = describe_time(scene, estimate(scene))
    assert text.startswith("time estimate about ") and text.endswith("not counting enumerate)")
    assert "not counting" not in describe_time(_scene(40), estimate(_scene(40)))
    full = _scene(40, analyses=("necessary", "sufficient", "mceip_mu", "mceip_lambda2"))
    assert "not counting" not in describe_time(full, estimate(full))


def test_validate_prints_the_time_estimate(scene_file):
    path = scene_file("name: v\nsystem: {type: block, nx: 30, ny: 15}\nmu: 1.1\nanalyses: [mceip_mu]\n")
    proc = run_cli_here("validate", str(path))
    assert proc.returncode == 0, proc.stderr
    assert "memory estimate" in proc.stdout and "time estimate about" in proc.stdout
