"""How often ``python -m app run`` returns to a module it had already left (issue 34).

Runs the default scene (pictures and report off) through the command line in this process under
a profiler, orders the modules of app/ by their first call, and counts the distinct caller ->
callee module pairs whose callee was first called before its caller: each is a return to a module
the data flow had already left (a utility module of app/common/ or app/linalg.py called again
later, a callback into the study). ``-v`` lists the pairs.

    .venv/bin/python benchmarks/module_trace.py [-v]
"""
from __future__ import annotations

import os
import pathlib
import sys
import tempfile

import yaml

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def main() -> None:
    from app.cli.main import main as cli
    app_dir = str(ROOT / "app")
    order: dict[str, int] = {}
    edges: set[tuple[str, str]] = set()

    def module(frame) -> str | None:
        f = frame.f_code.co_filename
        return os.path.relpath(f, app_dir) if f.startswith(app_dir) else None

    def profile(frame, event, arg):
        if event != "call" or (m := module(frame)) is None:
            return
        order.setdefault(m, len(order))
        back = frame.f_back
        while back is not None and module(back) is None:
            back = back.f_back
        if back is not None and (c := module(back)) != m:
            edges.add((c, m))

    with tempfile.TemporaryDirectory() as d:
        scene = yaml.safe_load((ROOT / "app/scenes/villechaise_block.yaml").read_text())
        scene["outputs"] = {"plots": False, "report": False}
        (pathlib.Path(d) / "scene.yaml").write_text(yaml.safe_dump(scene))
        sys.setprofile(profile)
        try:
            rc = cli(["run", f"{d}/scene.yaml", "-o", f"{d}/out", "--quiet"])
        finally:
            sys.setprofile(None)
    back = sorted((c, m) for c, m in edges if order[m] < order[c])
    print(f"exit {rc}: {len(order)} modules called, {len(edges)} caller -> callee module pairs, "
          f"{len(back)} returns to a module already left")
    if "-v" in sys.argv[1:]:
        for c, m in back:
            print(f"  {c} -> {m}")


if __name__ == "__main__":
    main()
