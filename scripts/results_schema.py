"""Generate docs/results-schema.json, the JSON Schema of results.json, from the pydantic models.

    .venv/bin/python scripts/results_schema.py           # rewrite docs/results-schema.json
    .venv/bin/python scripts/results_schema.py --check   # exit 1 if docs/results-schema.json is stale

The schema is ``app.io.schema.ResultsDocument.model_json_schema()``: the models the test suite
validates real results.json files with (tests/test_results_schema.py), so the two cannot drift.
"""
from __future__ import annotations

import json
import pathlib
import sys

ROOT = pathlib.Path(__file__).resolve().parents[1]
OUT = ROOT / "docs" / "results-schema.json"


def generate() -> str:
    """The text of docs/results-schema.json."""
    from app.io.schema import json_schema
    return json.dumps(json_schema(), indent=1, allow_nan=False) + "\n"


def main(argv: list[str]) -> int:
    """Write docs/results-schema.json, or with ``--check`` compare it with the generated text."""
    text = generate()
    if "--check" in argv:
        ok = OUT.exists() and OUT.read_text(encoding="utf-8") == text
        if not ok:
            print(f"{OUT} is stale: run {pathlib.Path(__file__).relative_to(ROOT)}", file=sys.stderr)
        return 0 if ok else 1
    OUT.parent.mkdir(exist_ok=True)
    OUT.write_text(text, encoding="utf-8")
    print(f"wrote {OUT.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    sys.path.insert(0, str(ROOT))
    sys.exit(main(sys.argv[1:]))
