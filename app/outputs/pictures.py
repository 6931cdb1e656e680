"""Draw what the scene's ``outputs`` ask for (plots, screenshots, report) from the results alone.

Runs on rank 0, after the study (``python -m app run``) or later on saved results
(``python -m app render RESULTS_DIR``): it never recomputes anything. The fields the screenshots
need were saved by the study's field stage (app/outputs/fields.py) in ``fields/fields.npz``.
"""
from __future__ import annotations

import contextlib
import json
import logging
import pathlib

from app.outputs.select import select_states
from app.stages import Stages

log = logging.getLogger(__name__)

PICTURE_STAGES = ("plots (matplotlib)", "screenshots (pyvista)", "report")


def outputs_config(results: dict) -> dict:
    return ((results.get("scene_config") or {}).get("outputs")) or {}


def wants_pictures(results: dict) -> bool:
    cfg = outputs_config(results)
    return bool(cfg.get("plots") or cfg.get("screenshots") or cfg.get("report"))


def _remove_old(folder: pathlib.Path, patterns: tuple[str, ...]) -> None:
    """Remove the pictures an earlier run or render left in one of the app's own picture folders."""
    if folder.is_dir():
        for pat in patterns:
            for p in folder.glob(pat):
                p.unlink()


@contextlib.contextmanager
def _survive(what: str, notes: list[str]):
    """A picture that cannot be drawn is a note, not a lost study: the results are still written."""
    try:
        yield
    except Exception as err:          # noqa: BLE001 - any drawing failure
        log.warning("%s failed", what, exc_info=True)
        notes.append(f"{what} failed ({type(err).__name__}: {err}); the results are complete: "
                     f"redraw with python -m app render")


def draw_outputs(results: dict, outdir: pathlib.Path, progress=None) -> list[str]:
    """Draw every picture asked for; returns the files drawn (relative to ``outdir``) and updates
    ``results["outputs"]`` (files, notes, pictured states) and ``results["stages"]``.

    ``results`` must be JSON-like (as read back from results.json) so that a run and a later
    render draw the same pictures.
    """
    cfg = outputs_config(results)
    record = results.setdefault("outputs", {"notes": [], "files": []})
    record.setdefault("notes", [])
    record.setdefault("files", [])
    if not wants_pictures(results):
        return []
    stages = Stages()
    # the run's stages; picture stages of an earlier drawing are replaced by this one's
    base = [s for s in results.get("stages", []) if s["name"] not in PICTURE_STAGES]
    pictured, notes = select_states(results["states"], cfg.get("states") or ["final"])
    record["pictured_states"] = pictured
    notes = [n for n in notes if n not in record["notes"]]
    plot_files, shot_files = [], []
    if cfg.get("plots"):
        with stages(PICTURE_STAGES[0]), _survive("plots", notes):
            from app.outputs.plots import draw_plots
            _remove_old(outdir / "plots", ("*.png", "*.svg"))
            plot_files, n = draw_plots(results, pictured, outdir / "plots")
            notes += n
    if cfg.get("screenshots") and not record.get("fields_not_applicable"):    # e.g. no mesh (matrices)
        with stages(PICTURE_STAGES[1]), _survive("screenshots", notes):
            from app.outputs.screenshots import draw_screenshots
            _remove_old(outdir / "screenshots", ("*.png",))
            shot_files, n = draw_screenshots(results, pictured, cfg["screenshots"], outdir / "screenshots",
                                             outdir / "fields" / "fields.npz", progress)
            notes += n
    record["notes"] += notes
    for n in notes:
        log.warning("%s", n)
    drawn = [p.relative_to(outdir).as_posix() for p in plot_files + shot_files]
    if cfg.get("report"):
        from app.outputs.report import versions, write_report
        results.setdefault("versions", versions())
        results["stages"] = base + stages.as_list()      # the report lists the stages before it
        with stages(PICTURE_STAGES[2]), _survive("report", record["notes"]):
            rep = write_report(results, outdir, pictured, plot_files, shot_files, record["notes"])
            drawn.append(rep.relative_to(outdir).as_posix())
    results["stages"] = base + stages.as_list()
    record["files"] = list(dict.fromkeys(record["files"] + drawn))
    for st in stages.as_list():
        log.info("%s: %.2f s", st["name"], st["seconds"])
    log.info("pictures: drew %d file(s)", len(drawn))
    return drawn


def draw_after_run(results: dict, outdir: pathlib.Path, progress=None) -> dict:
    """After a run (rank 0): the results as JSON data, with the pictures drawn if the scene asks.

    The drawing works on the results as they will be read back from results.json, so a later
    ``render`` draws exactly the same pictures.
    """
    if not wants_pictures(results):
        return results
    from app.outputs.results import json_clean
    data = json.loads(json.dumps(json_clean(results)))
    draw_outputs(data, outdir, progress)
    return data
