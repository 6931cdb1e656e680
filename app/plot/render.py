"""``python -m app render RESULTS_DIR``: redraw the pictures of a results folder, never recomputing
(of every case of a sweep folder: each ``cases/<case>/`` is a results folder of its own).

Reads ``results.json`` (the study, with the scene's ``outputs`` section in ``scene_config``)
and ``fields/fields.npz`` (the fields the screenshots need, saved by the run), and redraws the
plots, the screenshots and report.md. results.json is left as the run wrote it.

The folder is not trusted (app/io/untrusted.py): results.json is read only when it is a regular
file under :data:`RESULTS_MAX_BYTES` and is validated with the results.json models
(app/io/result.py) and its ``outputs`` section with the scene's own (app/scene/sections.py)
before anything is drawn. The pictures are drawn into a new hidden folder inside the results
folder and then moved into place by ``rename``: a file is replaced only when the folder's marker
records it as the app's (app/io/folder.py), the old pictures the app recorded are the only files
deleted, and no symbolic link is followed. Anything else in the way refuses the whole redraw
before a file is moved, with one ``error:`` line.
"""
from __future__ import annotations

import json
import os
import pathlib
import shutil
import stat
import sys
import tempfile

from app.io.result import StudyResult

#: the app's sub-folders a redraw writes into
PICTURE_FOLDERS = ("plots", "screenshots")


class Refused(Exception):
    """The folder cannot be redrawn; ``str(err)`` is the one line (after ``error: ``)."""


def render_main(args) -> int:
    """``python -m app render``: redraw the pictures of the results folder ``args.results`` on rank 0
    (the other ranks return at once). Exit status 0 when drawn or nothing is asked for, 1 when a
    picture failed, 2 when the folder is not one this app wrote, its results.json cannot be used
    or a file in the way is not the app's."""
    from mpi4py import MPI

    from app.common.logs import setup_logging
    setup_logging(args.log_level, MPI.COMM_WORLD.rank)
    if MPI.COMM_WORLD.rank != 0:          # nothing parallel to do: rank 0 draws
        return 0
    outdir = pathlib.Path(args.results)
    from app.io.folder import marker_kind
    if marker_kind(outdir) == "sweep" and not os.path.lexists(outdir / "results.json"):
        return _render_sweep(outdir, args)
    return _render_one(outdir, args)


def _render_sweep(outdir: pathlib.Path, args) -> int:
    """Redraw the pictures of every case of the sweep folder ``outdir`` (``cases/<case>/``, each a
    results folder of its own, read and redrawn as :func:`_render_one` does; a case folder that is
    not a real folder is skipped with a line). Exit status: the worst of the cases'."""
    cases = outdir / "cases"
    try:
        mode = os.lstat(cases).st_mode
    except FileNotFoundError:
        print(f"{outdir}: a sweep folder with no finished case: nothing to draw")
        return 0
    if not stat.S_ISDIR(mode):
        print(f"error: {cases}: not the folder this app wrote: nothing was redrawn", file=sys.stderr)
        return 2
    worst = 0
    for entry in sorted(os.scandir(cases), key=lambda e: e.name):
        if entry.name.startswith("."):                # a staging folder of an unfinished case
            continue
        if not entry.is_dir(follow_symlinks=False):
            print(f"error: {cases / entry.name}: not a case folder this app wrote (skipped)", file=sys.stderr)
            worst = max(worst, 2)
            continue
        worst = max(worst, _render_one(cases / entry.name, args))
    return worst


def _render_one(outdir: pathlib.Path, args) -> int:
    """Redraw one results folder (``render``'s body for a study)."""
    try:
        study = with_options(read_results(outdir), getattr(args, "states", None), getattr(args, "field", None))
    except Refused as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    from app.plot.pictures import outputs_config, wants_pictures
    if not wants_pictures(study):
        if not args.quiet:
            print(f"{outdir}: nothing to draw: the scene's 'outputs' ask for no plots, screenshots or report")
        return 0
    from app.common.progress import Progress
    try:
        drawn, failed, notes = redraw(study, outdir, Progress(enabled=not args.quiet))
    except Refused as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    if not args.quiet:
        cfg = outputs_config(study)
        print(f"{outdir}: redrew {len(drawn)} file(s) ("
              + ", ".join(k for k in ("plots", "screenshots", "report") if cfg.get(k)) + ")")
        for f in drawn:
            print(f"  {outdir / f}")
    for n in notes:                       # e.g. a state asked for with --states whose field was not saved
        print(f"note: {n}", file=sys.stderr)
    for n in failed:
        print(f"error: {n}", file=sys.stderr)
    return 1 if failed else 0


def _pydantic_line(err) -> str:
    """The first error of a pydantic ValidationError as ``key.path: message (got VALUE)``."""
    first = err.errors()[0]
    where = ".".join(str(p) for p in first.get("loc", ())) or "the document"
    got = repr(first.get("input"))
    got = got if len(got) <= 60 else got[:57] + "..."
    return f"{where}: {first.get('msg', 'invalid')} (got {got})"


def read_results(outdir: pathlib.Path) -> StudyResult:
    """The study of the results folder ``outdir`` (its results.json), with its scene's ``outputs``
    validated; :class:`Refused` when the folder or its results.json cannot be used."""
    from pydantic import ValidationError

    from app.io import result as schema
    from app.io.document import from_document
    from app.io.folder import MARKER, marker_kind, recorded
    from app.io.untrusted import RESULTS_MAX_BYTES, UntrustedFile, read_bytes
    res_file = outdir / "results.json"
    if os.path.lexists(res_file) and marker_kind(outdir) is None:
        # redrawing replaces the pictures in plots/ and screenshots/: only in a folder the app wrote
        raise Refused(f"{outdir}: not a results folder written by this app (no {MARKER}): nothing is redrawn there")
    if not os.path.lexists(res_file):
        raise Refused(f"{outdir}: no results.json here (not a results folder, or the run did not finish)")
    if marker_kind(outdir) != "results":
        raise Refused(f"{outdir}: a {marker_kind(outdir)} folder of this app, not the results of one study: "
                      f"render one of its results folders")
    if recorded(outdir) is None:
        raise Refused(f"{outdir}: its marker has no usable list of its files (written by an earlier version of this "
                      f"app, or changed): its pictures cannot be told from other files; run the scene again to redraw")
    for name in PICTURE_FOLDERS + ("fields",):
        _real_folder_or_missing(outdir / name)
    try:
        text = read_bytes(res_file, RESULTS_MAX_BYTES)
    except UntrustedFile as err:
        raise Refused(str(err)) from None
    try:
        schema.validate(text)
    except ValidationError as err:
        raise Refused(f"{res_file}: {_pydantic_line(err)}: not a results.json this version can redraw") from None
    except ValueError as err:            # not JSON data: NaN or Infinity literals, nested too deeply
        raise Refused(f"{res_file}: {err}: not a results.json this version can redraw") from None
    try:
        # the validated text once more, its non-finite numbers (null, listed in non_finite) as floats
        study = StudyResult.from_dict(from_document(json.loads(text)))
    except RecursionError:
        raise Refused(f"{res_file}: nested too deeply to be read") from None
    except ValidationError as err:
        raise Refused(f"{res_file}: {_pydantic_line(err)}: not a results.json this version can redraw") from None
    except ValueError as err:
        raise Refused(f"{res_file}: cannot be read ({err})") from None
    outputs = _outputs(study.scene_config.get("outputs"), res_file)
    study = study.model_copy(update={"scene_config": {**study.scene_config, "outputs": outputs}})
    if outputs.get("screenshots"):
        _check_fields(outdir / "fields" / "fields.npz")
    return study


def with_options(study: StudyResult, states: list[str] | None, field: str | None) -> StudyResult:
    """The study with the command line's choices of pictured states (``--states``: the selectors of
    ``outputs.states``, a state index or ``final``, ``first_mceip_mu``, ``all_distinct``) and of the
    screenshots' field (``--field``) in place of its scene's, validated as the scene's own."""
    if not states and not field:
        return study
    outputs = dict(study.scene_config.get("outputs") or {})
    if states:
        outputs["states"] = [int(x) if x.strip().lstrip("-").isdigit() else x.strip() for x in states]
    if field:
        if not outputs.get("screenshots"):
            raise Refused("--field: the scene asked for no screenshots (outputs.screenshots), so there are none "
                          "to draw with another field")
        outputs["screenshots"] = {**outputs["screenshots"], "field": field}
    checked = _outputs(outputs, pathlib.Path("--states/--field"))
    return study.model_copy(update={"scene_config": {**study.scene_config, "outputs": checked}})


def _check_fields(path: pathlib.Path) -> None:
    """fields.npz, when there, is a regular file whose ``.npy`` headers match its members and fit
    in memory (checked before any array is read)."""
    from app.io.untrusted import UntrustedFile, check_npz, memory_limit, opened
    if not os.path.lexists(path):
        return                                   # the screenshots are left out with a note
    try:
        with opened(path, int(min(memory_limit(), 2**62))) as f:
            check_npz(f, str(path))
    except UntrustedFile as err:
        raise Refused(str(err)) from None


def _outputs(raw, res_file: pathlib.Path) -> dict:
    """The scene's ``outputs`` section of results.json, validated by the scene's own model (its
    bounds on ``screenshots.resolution``, the allowed ``screenshots.field``, ...)."""
    from pydantic import ValidationError

    from app.scene.sections import Outputs
    try:
        return Outputs.model_validate(raw if raw is not None else {}).model_dump(mode="json")
    except ValidationError as err:
        raise Refused(f"{res_file}: scene_config.outputs.{_pydantic_line(err)}") from None


def _real_folder_or_missing(path: pathlib.Path) -> None:
    """``path`` is absent or a real folder (not a symbolic link to one)."""
    try:
        mode = os.lstat(path).st_mode
    except FileNotFoundError:
        return
    if not stat.S_ISDIR(mode):
        from app.io.untrusted import kind_of
        raise Refused(f"{path}: is {kind_of(mode)}, not the folder this app wrote: nothing was redrawn")


def redraw(study: StudyResult, outdir: pathlib.Path, progress=None) -> tuple[list[str], list[str], list[str]]:
    """Draw the pictures of ``study`` into a new hidden folder in ``outdir`` and move them into
    place (:func:`install`); returns (the files drawn relative to ``outdir``, the notes of the
    pictures that failed, the other notes: pictures left out and why). results.json is not rewritten."""
    from app.plot.pictures import draw_outputs
    before = len(study.outputs.notes) if study.outputs is not None else 0
    staging = pathlib.Path(tempfile.mkdtemp(dir=outdir, prefix=".render-"))
    try:
        drawn_study, drawn = draw_outputs(study, staging, progress, fields=outdir / "fields" / "fields.npz")
        install(staging, outdir, drawn)
    finally:
        shutil.rmtree(staging, ignore_errors=True)      # this call's own folder (what is left of it)
    new_notes = drawn_study.outputs.notes[before:]
    failed = [n for n in new_notes if " failed (" in n]
    return drawn, failed, [n for n in new_notes if " failed (" not in n]


def _plan_parent(outdir: pathlib.Path, rel: str, folders: set[str], create: list[str]) -> None:
    """Every folder above ``rel`` is a recorded real folder of the app, or absent (then created)."""
    parts = pathlib.PurePosixPath(rel).parts[:-1]
    for k in range(1, len(parts) + 1):
        sub = "/".join(parts[:k])
        try:
            mode = os.lstat(outdir / sub).st_mode
        except FileNotFoundError:
            if sub not in create:
                create.append(sub)
            continue
        if not stat.S_ISDIR(mode) or sub not in folders:
            raise Refused(f"{outdir / sub}: not a folder this app recorded writing: nothing was redrawn "
                          f"(move it away to redraw)")


def _plan_target(outdir: pathlib.Path, rel: str, files: set[str]) -> None:
    """The file ``rel`` is absent, or a regular file the app recorded writing (it is replaced)."""
    try:
        mode = os.lstat(outdir / rel).st_mode
    except FileNotFoundError:
        return
    if not stat.S_ISREG(mode) or rel not in files:
        raise Refused(f"{outdir / rel}: not a file this app recorded writing (it is kept): nothing was redrawn "
                      f"(move it away to redraw)")


def install(staging: pathlib.Path, outdir: pathlib.Path, drawn: list[str]) -> None:
    """Move the files ``drawn`` (relative paths in ``staging``) into ``outdir`` and delete the
    pictures of the earlier drawing that were not drawn again; record the result in the marker.

    Everything is checked before anything moves: a path in the way that the app did not record
    (a user's file, a symbolic link, a FIFO) refuses the whole redraw. A file is replaced by
    ``rename`` (never written through: a hard link elsewhere keeps the old content)."""
    from app.io.folder import recorded, write_marker
    known = recorded(outdir)
    if known is None:
        raise Refused(f"{outdir}: its marker changed while the pictures were drawn: nothing was redrawn")
    folders, files = known
    create: list[str] = []
    for rel in drawn:
        _plan_parent(outdir, rel, folders, create)
        _plan_target(outdir, rel, files)
    # the earlier pictures directly in a picture folder that was drawn again (its parent checked above)
    redrawn = {rel.split("/")[0] for rel in drawn if rel.count("/") == 1}
    stale = sorted(f for f in files if f.count("/") == 1 and f.split("/")[0] in redrawn and f not in drawn)
    for sub in create:
        os.mkdir(outdir / sub)
        folders.add(sub)
    for rel in drawn:
        os.replace(staging / rel, outdir / rel)
        files.add(rel)
    for rel in stale:
        path = outdir / rel
        try:
            if stat.S_ISREG(os.lstat(path).st_mode):
                os.unlink(path)
        except FileNotFoundError:
            pass
        files.discard(rel)
    write_marker(outdir, "results", (sorted(folders), sorted(files)))
