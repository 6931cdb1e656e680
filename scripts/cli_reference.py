"""Generate docs/cli.md, the command-line reference, from app/cli/main.py's argparse parser.

    .venv/bin/python scripts/cli_reference.py           # rewrite docs/cli.md
    .venv/bin/python scripts/cli_reference.py --check   # exit 1 if docs/cli.md is stale

The text is argparse's own ``--help`` of the program and of every command (at a fixed width of
100 columns), so it cannot drift from the parser; tests/test_docs.py fails when the committed file
differs from this script's output.
"""
from __future__ import annotations

import argparse
import os
import pathlib
import sys

from _generated import write_or_check  # beside this script: scripts/ is on sys.path

ROOT = pathlib.Path(__file__).resolve().parents[1]
OUT = ROOT / "docs" / "cli.md"


def generate() -> str:
    os.environ["COLUMNS"] = "100"            # argparse wraps at the terminal width
    sys.path.insert(0, str(ROOT))
    try:
        from app.cli.main import _parser
        from app.common.petsc_options import PREFIXES
    finally:
        sys.path.pop(0)
    parser = _parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    out = ["# Command line", "",
           "Generated from the argparse parser of `app/cli/main.py` by `scripts/cli_reference.py` (do not edit:",
           "run that script after changing the parser). Also installed as the `contact-divergence`",
           "console script.", "", "## python -m app", "", "```text", parser.format_help().rstrip(), "```", ""]
    for name, cmd in sub.choices.items():
        out += [f"## python -m app {name}", "", "```text", cmd.format_help().rstrip(), "```", ""]
    out += ["## PETSc and SLEPc options", "",
            "Any PETSc option after the scene file reaches PETSc's options database; the app's solvers",
            "read it under these prefixes (see [PETSc options](petsc.md)):", ""]
    out += [f"- `{p}`: {d}" for p, d in PREFIXES.items()]
    return "\n".join(out) + "\n"


def main(argv: list[str]) -> int:
    """Write docs/cli.md, or with ``--check`` compare it with the generated text."""
    return write_or_check(OUT, generate(), argv, pathlib.Path(__file__), ROOT)


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
