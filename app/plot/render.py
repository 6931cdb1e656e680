"""``python -m app render RESULTS_DIR``: redraw the pictures of a results folder, never recomputing.

Reads ``results.json`` (the study, with the scene's ``outputs`` section in ``scene_config``)
and ``fields/fields.npz`` (the fields the screenshots need, saved by the run), and redraws the
plots, the screenshots and report.md. results.json is left as the run wrote it.
"""
from __future__ import annotations

import json
import pathlib
import sys


def render_main(args) -> int:
    """``python -m app render``: redraw the pictures of the results folder ``args.results`` on rank 0
    (the other ranks return at once). Exit status 0 when drawn or nothing is asked for, 1 when a
    picture failed, 2 when the folder is not one this app wrote or its results.json cannot be
    used."""
    from mpi4py import MPI

    from app.common.logs import setup_logging
    setup_logging(args.log_level, MPI.COMM_WORLD.rank)
    if MPI.COMM_WORLD.rank != 0:          # nothing parallel to do: rank 0 draws
        return 0
    outdir = pathlib.Path(args.results)
    res_file = outdir / "results.json"
    from app.io.document import from_document
    from app.io.folder import MARKER, marker_kind
    if res_file.is_file() and marker_kind(outdir) is None:
        # redrawing replaces the pictures in plots/ and screenshots/: only in a folder the app wrote
        print(f"error: {outdir}: not a results folder written by this app (no {MARKER}): nothing is redrawn there",
              file=sys.stderr)
        return 2
    if not res_file.is_file():
        print(f"error: {outdir}: no results.json here (not a results folder, or the run did not finish)",
              file=sys.stderr)
        return 2
    try:
        results = from_document(json.loads(res_file.read_text(encoding="utf-8")))
    except (OSError, ValueError) as err:
        print(f"error: {res_file}: cannot be read ({err})", file=sys.stderr)
        return 2
    from app.plot.pictures import draw_outputs, outputs_config, wants_pictures
    if "scene_config" not in results:
        print(f"error: {res_file}: written by an older version (no scene_config): nothing to redraw from",
              file=sys.stderr)
        return 2
    if not wants_pictures(results):
        if not args.quiet:
            print(f"{outdir}: nothing to draw: the scene's 'outputs' ask for no plots, screenshots or report")
        return 0
    from app.common.progress import Progress
    before = len((results.get("outputs") or {}).get("notes") or [])
    drawn = draw_outputs(results, outdir, Progress(enabled=not args.quiet))
    failed = [n for n in results["outputs"]["notes"][before:] if " failed (" in n]
    if not args.quiet:
        cfg = outputs_config(results)
        print(f"{outdir}: redrew {len(drawn)} file(s) ("
              + ", ".join(k for k in ("plots", "screenshots", "report") if cfg.get(k)) + ")")
        for f in drawn:
            print(f"  {outdir / f}")
    for n in failed:
        print(f"error: {n}", file=sys.stderr)
    return 1 if failed else 0
