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
    x, label, is_load = plots.load_axis(r.states, r.units.length)
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
    x, label, is_load = plots.load_axis(r.states, r.units.length)
    assert not is_load and label == "load step (state index)" and list(x) == [s.index for s in r.states]
    plots.draw_plots(r, [r.final.index], tmp_path)
    assert figures["mceip_mu"].axes[0].get_xlabel() == label
