"""``outputs.screenshots.animate`` (issue 35): beside each mode's picture an animated GIF of the
mode growing as the divergence it predicts (a0 exp(lambda t) where lambda^2 > 0 is known, linear
for MCEIP-mu's static mode), the view fixed, the report showing it."""
import json

import numpy as np
import pytest
import yaml
from conftest import ROOT, run_cli


def test_each_drawn_mode_is_animated(tmp_path):
    from PIL import Image

    from app.io.select import FRAMES
    s = yaml.safe_load((ROOT / "app/scenes/villechaise_block.yaml").read_text())
    s.update(analyses=["mceip_mu", "mceip_lambda2"], mceip_lambda2_mu=2.0,
             outputs={"report": True, "paraview": True, "states": ["final"],
                      "screenshots": {"animate": True, "resolution": [360, 240]}})
    s["system"].update(nx=12, ny=6)
    (tmp_path / "s.yaml").write_text(yaml.safe_dump(s))
    p = run_cli("run", str(tmp_path / "s.yaml"), "-o", str(tmp_path / "out"), "-q")
    assert p.returncode == 0, p.stderr
    shots = tmp_path / "out" / "screenshots"
    pngs = sorted(f.stem for f in shots.glob("mode_*.png"))
    gifs = sorted(f.stem for f in shots.glob("mode_*.gif"))
    assert pngs and gifs == pngs                                   # one animation per mode picture
    assert any("mceip_lambda2" in g for g in gifs)                # a mode with lambda^2 > 0
    for name in gifs:
        with Image.open(shots / f"{name}.gif") as im:
            assert im.n_frames == FRAMES and im.size == (360, 240)
            frames = []
            for k in (0, FRAMES - 1):
                im.seek(k)
                frames.append(np.asarray(im.convert("RGB"), dtype=float))
        assert np.abs(frames[0] - frames[1]).mean() > 0.5           # the mode grows
    res = json.loads((tmp_path / "out" / "results.json").read_text())
    assert {f"screenshots/{g}.gif" for g in gifs} <= set(res["outputs"]["files"])
    report = (tmp_path / "out" / "report.md").read_text()
    assert all(f"({'screenshots'}/{g}.gif)" in report for g in gifs) and "a0 exp(lambda t)" in report
    # ParaView: the same growth as a time series per animated mode, its frames at the GIF's times
    import meshio

    from app.io.select import mode_growth
    modes = meshio.read(tmp_path / "out" / "paraview" / "modes.vtu").point_data
    with np.load(tmp_path / "out" / "fields" / "fields.npz") as z:
        meta = {m["name"]: m for m in json.loads(str(z["modes_json"]))}
    for name in gifs:
        field = name[len("mode_"):]
        problem, value = meta[field]["problem"], meta[field]["value"]
        with meshio.xdmf.TimeSeriesReader(str(tmp_path / "out" / "paraview" / f"{name}.xdmf")) as r:
            r.read_points_cells()
            steps = [r.read_data(k) for k in range(r.num_steps)]
        growth = mode_growth(problem, value)
        assert len(steps) == FRAMES == len(growth)
        for (t, a), (time, point_data, _) in zip(growth, steps):
            assert time == pytest.approx(a if t is None else t, rel=1e-12)
            assert np.allclose(point_data["mode"], a * modes[field], rtol=0, atol=1e-12)
        assert np.abs(np.linalg.norm(steps[-1][1]["mode"], axis=1).max() - 1.0) < 1e-9
        assert f"paraview/{name}.xdmf" in res["outputs"]["files"]
