"""The thumbnails of docs/outputs.md (docs/img/): the pictures of the default study, a sweep, a
refinement study and a Gmsh body, made by the app and shrunk.

    .venv/bin/python scripts/doc_thumbnails.py        # about 2 minutes on one core

Each picture is made by the command a user runs (``python -m app run``) in a temporary folder;
the thumbnails are 440 pixels wide. Run it again when a picture changes.
"""
from __future__ import annotations

import pathlib
import subprocess
import sys
import tempfile

import yaml

ROOT = pathlib.Path(__file__).resolve().parents[1]
OUT = ROOT / "docs" / "img"
WIDTH = 440


def _run(scene: dict | pathlib.Path, out: pathlib.Path, *extra: str) -> None:
    if isinstance(scene, dict):
        path = out.with_suffix(".yaml")
        path.write_text(yaml.safe_dump(scene, sort_keys=False))
    else:
        path = scene
    cmd = [sys.executable, "-m", "app", "run", str(path), "-o", str(out), "-q", *extra]
    subprocess.run(cmd, check=True, cwd=ROOT)


def _thumb(src: pathlib.Path, name: str) -> None:
    from PIL import Image
    with Image.open(src) as im:
        im = im.convert("RGB")
        h = round(im.height * WIDTH / im.width)
        small = im.resize((WIDTH, h), Image.LANCZOS).convert("P", palette=Image.ADAPTIVE, colors=128)
        small.save(OUT / f"{name}.png", optimize=True)
    print(f"docs/img/{name}.png  <- {src.relative_to(src.parents[2])}")


def main() -> int:
    OUT.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        t = pathlib.Path(tmp)
        # the default study (the paper's block), its plots and screenshots
        _run(ROOT / "app" / "scenes" / "villechaise_block.yaml", t / "block")
        for name in ("status_map", "mceip_mu", "necessary", "reactions"):
            _thumb(t / "block" / "plots" / f"{name}.png", f"block_{name}")
        shots = sorted((t / "block" / "screenshots").glob("*.png"))
        _thumb(next(p for p in shots if p.name.startswith("state_")), "block_state")
        _thumb(next(p for p in shots if "mceip_mu" in p.name), "block_mode")
        # a Gmsh body: the L-shaped body of app/scenes/gmsh/
        _run(ROOT / "app" / "scenes" / "gmsh" / "l_shape.yaml", t / "lshape")
        _thumb(t / "lshape" / "plots" / "mceip_mu.png", "gmsh_mceip_mu")
        _thumb(next(iter(sorted((t / "lshape" / "screenshots").glob("mode_*.png")))), "gmsh_mode")
        # a sweep of the friction coefficient (coarse block)
        sweep = yaml.safe_load((ROOT / "app" / "scenes" / "sweep_mu.yaml").read_text())
        sweep["system"].update(nx=10, ny=5)
        sweep["loading"]["tangential_step"] = 0.05
        _run(sweep, t / "sweep")
        _thumb(t / "sweep" / "plots" / "mu.png", "sweep_mu")
        _thumb(t / "sweep" / "plots" / "mceip_mu_along_the_loading.png", "sweep_along")
        # a refinement study (three levels, P1 and P2, plane stress)
        ref = yaml.safe_load((ROOT / "app" / "scenes" / "refinement.yaml").read_text())
        ref["refinement"].update(levels=[10, 20, 40], degrees=[1, 2], planes=["stress"])
        _run(ref, t / "refinement")
        _thumb(t / "refinement" / "refinement.png", "refinement_h")
        _thumb(t / "refinement" / "refinement_cost.png", "refinement_cost")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
