"""Shared by the scripts that generate a file of docs/ (scene_keys.py, results_schema.py,
cli_reference.py): write it, or with ``--check`` say whether the committed file is stale."""
from __future__ import annotations

import pathlib
import sys


def write_or_check(out: pathlib.Path, text: str, argv: list[str], script: pathlib.Path, root: pathlib.Path) -> int:
    """Write ``text`` to ``out`` (0), or with ``--check`` in ``argv`` compare: 0 when equal, 1 and
    a line naming ``script`` to run when stale."""
    if "--check" in argv:
        ok = out.exists() and out.read_text(encoding="utf-8") == text
        if not ok:
            print(f"{out.relative_to(root)} is stale: run .venv/bin/python {script.relative_to(root)}", file=sys.stderr)
        return 0 if ok else 1
    out.parent.mkdir(exist_ok=True)
    out.write_text(text, encoding="utf-8")
    print(f"wrote {out.relative_to(root)}")
    return 0
