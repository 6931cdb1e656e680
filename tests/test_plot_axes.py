"""The plots along the loading put each state at its load, in the scene's length unit, where the
loading is the motion of CD (the block: the distance CD travelled, pressed then dragged), and at
its index otherwise (two particles: one state); every axis names its quantity and unit
(issue 35). Checked on matplotlib's own objects."""
import numpy as np
import pytest
from mpi4py import MPI

import app.plot.plots as plots
from app.scene.schema import parse_scene
from app.study.run import study

BLOCK = {"name": "b", "mu": 1.1, "analyses": ["necessary", "mceip_mu"],
         "system": {"type": "block", "nx": 8, "ny": 4},
         "loading": {"normal_force": 55.0, "normal_steps": 4, "tangential_step": 0.5, "tangential_max": 3.0}}


@pytest.fixture
def figures(monkeypatch):
    """The figures the plot functions save, by file stem (still open)."""
    kept = {}

    def save(fig, path):
        kept[path.name] = fig
        return []

    monkeypatch.setattr(plots, "_save", save)
    yield kept
    import matplotlib.pyplot as plt
    for fig in kept.values():
        plt.close(fig)


def test_block_plots_are_drawn_against_the_load(figures, tmp_path):
    r = study(parse_scene(BLOCK), MPI.COMM_WORLD)
    x, label, is_load = plots.load_axis(r.states, r.units)
    assert is_load and label.endswith("[mm]") and np.all(np.diff(x) > 0)
    # the distance CD travelled: the press depth, then the drag
    depth = abs(r.states[BLOCK["loading"]["normal_steps"] - 1].load.u_y)
    assert x[BLOCK["loading"]["normal_steps"] - 1] == pytest.approx(depth)
    assert x[-1] == pytest.approx(depth + abs(r.final.load.u_x))
    plots.draw_plots(r, [r.final.index], tmp_path)
    assert set(figures) == {"status_map", "reactions", "mceip_mu", "necessary"}
    for name in ("status_map", "mceip_mu", "necessary"):
        ax = figures[name].axes[0]
        assert ax.get_xlabel() == label, name
        lo, hi = ax.get_xlim()
        assert lo <= x[0] and hi >= x[-1] and hi < x[-1] + 1.0, name          # in mm, not in states
        assert ax.get_ylabel(), name
    assert figures["necessary"].axes[0].get_ylabel().endswith("[N/mm]")
    assert figures["status_map"].axes[0].get_ylabel().startswith("contact node position x [mm]")
    assert all("[N]" in a.get_ylabel() for a in figures["reactions"].axes[:2])


def test_a_system_without_a_cd_motion_keeps_the_state_index(figures, tmp_path):
    r = study(parse_scene({"name": "two", "mu": 2.5, "analyses": ["mceip_mu"],
                           "system": {"type": "two_particles", "k": 1, "m": 1, "phi_deg": 30, "signs": [1, 1]}}),
              MPI.COMM_WORLD)
    x, label, is_load = plots.load_axis(r.states, r.units)
    assert not is_load and label == "load step (state index)" and list(x) == [s.index for s in r.states]
    plots.draw_plots(r, [r.final.index], tmp_path)
    assert figures["mceip_mu"].axes[0].get_xlabel() == label


def test_a_loading_program_is_drawn_against_its_own_parameters(figures, tmp_path):
    """A Gmsh body's program ("press CD, then drag it"): the distance its motion parameters travel,
    which for the paper's block as a Gmsh body is the built-in block's distance CD travelled (an
    independent computation of the same axis: the block's from u_x and u_y, the program's from its
    parameters), the same after a rotation of the whole scene (a distance)."""
    from test_gmsh_body import block_scene, gmsh_scene, write_block_msh

    from app.io.result import StudyResult
    from app.scene.schema import parse_scene as parse
    ref = study(parse(block_scene(10, 5, "crossed")), MPI.COMM_WORLD)
    x_ref, _, _ = plots.load_axis(ref.states, ref.units)
    got = study(parse(gmsh_scene(write_block_msh(tmp_path / "b.msh", 10, 5, "crossed"))), MPI.COMM_WORLD)
    x, label, is_load = plots.load_axis(got.states, got.units)
    assert is_load and label == "prescribed motion of CD, travelled along the program [mm]"
    assert len(x) == len(x_ref) and np.allclose(x, x_ref, rtol=1e-9, atol=0)
    rot = study(parse(gmsh_scene(write_block_msh(tmp_path / "r.msh", 10, 5, "crossed", 30.0), angle_deg=30.0)),
                MPI.COMM_WORLD)
    assert np.allclose(plots.load_axis(rot.states, rot.units)[0], x, rtol=1e-9, atol=0)
    plots.draw_plots(got, [got.final.index], tmp_path)
    for name in ("status_map", "mceip_mu"):
        assert figures[name].axes[0].get_xlabel() == label
    # the typed result's own JSON round trip gives the same axis (render redraws from results.json)
    again = StudyResult.from_json(got.to_json())
    assert np.array_equal(plots.load_axis(again.states, again.units)[0], x)


def test_parameters_of_different_units_fall_back_to_the_state_index():
    """A program pushing with a force, then dragging by a motion, has no one load unit: the state index."""
    from app.io.result import StudyResult
    from app.io.select import parameter_unit
    units = {"length": "mm", "force": "N", "stress": "MPa", "time": "s"}
    assert [parameter_unit(n, units) for n in ("motion.top.tx", "motion.top.rz", "force.top.y", "traction.side.x",
                                               "gravity.y", "pressure.top.x")] == ["mm", "rad", "N", "MPa",
                                                                                   "mm/s^2", None]
    r = study(parse_scene(BLOCK), MPI.COMM_WORLD).to_dict()
    for k, s in enumerate(r["states"]):
        s["load"] = {"phase": 0 if k < 3 else 1, "step": k,
                     "parameters": {"force.top.y": -1.0 * min(k + 1, 3)} if k < 3
                     else {"force.top.y": -3.0, "motion.top.tx": 0.1 * (k - 2)}}
    mixed = StudyResult.from_dict(r)
    x, label, is_load = plots.load_axis(mixed.states, mixed.units)
    assert not is_load and label == "load step (state index)"
