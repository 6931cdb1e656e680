"""Generate docs/results-schema.json, the JSON Schema of results.json, from the pydantic models.

    .venv/bin/python scripts/results_schema.py           # rewrite docs/results-schema.json
    .venv/bin/python scripts/results_schema.py --check   # exit 1 if docs/results-schema.json is stale

The schema is ``app.io.result.StudyResult.model_json_schema()``: the models the test suite
validates real results.json files with (tests/test_results_schema.py), so the two cannot drift.
"""
from __future__ import annotations

import json
import pathlib
import sys

from _generated import write_or_check  # beside this script: scripts/ is on sys.path

ROOT = pathlib.Path(__file__).resolve().parents[1]
OUT = ROOT / "docs" / "results-schema.json"


def generate() -> str:
    """The text of docs/results-schema.json."""
    from app.io.result import json_schema
    return json.dumps(json_schema(), indent=1, allow_nan=False) + "\n"


def main(argv: list[str]) -> int:
    """Write docs/results-schema.json, or with ``--check`` compare it with the generated text."""
    return write_or_check(OUT, generate(), argv, pathlib.Path(__file__), ROOT)


if __name__ == "__main__":
    sys.path.insert(0, str(ROOT))
    sys.exit(main(sys.argv[1:]))
