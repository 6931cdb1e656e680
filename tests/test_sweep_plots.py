"""A sweep of a user's own Gmsh body reads as well as one of the block (issue 35): its load columns
come from the loading program's parameters (with their units), and the plots are titled in words,
with units, and mark the cases whose path ended otherwise. Checked on matplotlib's own objects."""
from __future__ import annotations

import csv
import json

import pytest
from mpi4py import MPI
from test_gmsh_body import gmsh_scene, write_block_msh


@pytest.mark.skipif(MPI.COMM_WORLD.size > 1, reason="runs the serial sweep in this process")
def test_a_gmsh_body_sweep_has_load_columns_and_plots_in_words(tmp_path, monkeypatch):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from app.scene.schema import parse_scene
    from app.study.sweep import expand, run_sweep
    data = gmsh_scene(write_block_msh(tmp_path / "b.msh", 10, 5, "crossed"))
    # a short drag: with mu = 0.2 the block slides grossly, with mu = 1.1 it does not get there
    data["system"]["program"][1].update(steps=20, displacement={"CD": {"translation": [-2.0, 0.0]}})
    data["sweep"] = {"parameters": {"mu": [0.2, 0.6, 1.1]}}
    scene = parse_scene(data, str(tmp_path / "s.yaml"))
    cases = expand(scene)
    kept = []
    monkeypatch.setattr(plt, "close", lambda fig=None: kept.append(fig))
    assert run_sweep(scene, cases, MPI.COMM_WORLD, tmp_path / "out", quiet=True) == 0
    out = tmp_path / "out"
    with open(out / "sweep.csv") as f:
        rows = list(csv.DictReader(f))
    doc = json.loads((out / "sweep.json").read_text())
    header = list(rows[0])
    for col in ("final_load", "first_mceip_mu_load", "load_label", "final:motion.CD.tx [mm]",
                "final:motion.CD.ty [mm]"):
        assert col in header, col
    for c, row, jrow in zip(cases, rows, doc["cases"]):
        res = json.loads((out / "cases" / c.name / "results.json").read_text())
        last = res["states"][-1]["load"]["parameters"]
        assert float(row["final:motion.CD.tx [mm]"]) == pytest.approx(last["motion.CD.tx"], rel=1e-12)
        # the press then the drag: the distance travelled is the press depth plus the drag
        assert jrow["final_load"] == pytest.approx(abs(last["motion.CD.ty"]) + abs(last["motion.CD.tx"]), rel=1e-9)
        assert jrow["load_label"].endswith("[mm]")
    ends = [r["path_end"] for r in doc["cases"]]
    assert ends[0] != ends[-1], ends                      # the sweep has a case that ended otherwise
    figs = [f for f in kept if f is not None and f._suptitle is not None]
    assert len(figs) == 1
    # the comparison: one curve per case, each case's smallest MCEIP-mu against its load
    (compare,) = [f for f in kept if f is not None and f._suptitle is None]
    ax = compare.axes[0]
    assert ax.get_xlabel() == "prescribed motion of CD, travelled along the program [mm]"
    assert [t.get_text() for t in ax.get_legend().get_texts()] == [c.name for c in cases]
    assert (out / "plots" / "mceip_mu_along_the_loading.png").is_file()
    fig = figs[0]
    assert "friction coefficient \u03bc" in fig._suptitle.get_text()
    axes = [a for a in fig.axes if a.get_visible()]
    titles = [a.get_title() for a in axes]
    assert all("_" not in t for t in titles) and not any("wall" in t for t in titles), titles
    assert all(a.get_ylabel() and a.get_xlabel() == "friction coefficient \u03bc" for a in axes)
    load_axes = [a for a in axes if a.get_title().startswith("load ")]
    assert load_axes and all(a.get_ylabel().endswith("[mm]") for a in load_axes)
    hollow = [ln for a in axes for ln in a.get_lines() if ln.get_markerfacecolor() == "white"]
    assert hollow, "the case whose path ended otherwise has open markers"
    assert any("open markers" in t.get_text() for t in fig.texts)


def test_counts_spanning_a_decade_are_drawn_on_a_log_axis(tmp_path):
    """A count (states, slip nodes) spanning more than a decade goes on a log axis (whole-number
    ticks only on a linear one: asking a log axis for them failed the whole sweep's plots)."""
    import matplotlib
    matplotlib.use("Agg")

    from app.scene.schema import parse_scene
    from app.scene.sweep import expand
    from app.study.sweep_table import write_plots
    scene = parse_scene({"name": "s", "mu": 1.1, "system": {"type": "block", "nx": 4, "ny": 2},
                         "sweep": {"parameters": {"mu": [0.5, 1.0, 1.5]}}})
    cases = expand(scene)
    rows = {c.index: {"status": "ok", "path_end": "gross sliding", "n_states": n, "final_n_slip": s}
            for c, n, s in zip(cases, (12, 60, 400), (1, 5, 30))}
    (path,) = write_plots(tmp_path, "product", cases, rows, {"length": "mm"})
    assert path.stat().st_size > 0
