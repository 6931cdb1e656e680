"""Results do not depend on the number of MPI ranks (1, 2, 3), to 1e-8 relative."""
import json
import os
import subprocess

import pytest
from conftest import PY, ROOT, run_cli, run_cli_here

SCENE = """\
name: mpi-check
system: {type: block, nx: 10, ny: 5}
mu: 1.1
mceip_lambda2_mu: 2.0
analyses: [necessary, sufficient, mceip_mu, mceip_lambda2]
"""


def _numbers(res):
    out = []
    for s in res["states"]:
        out.append(("status", tuple(n["status"] for n in s["nodes"])))
        out += [("r", n["r_N"]) for n in s["nodes"]] + [("r", n["r_T"]) for n in s["nodes"]]
        a = s["analyses"]
        out.append(("eig", a["necessary"]["min_eig_K_sym"]))
        out.append(("eig", a["necessary"]["min_eig_M_sym"]))
        out.append(("n", len(a["sufficient"]["lambda2"])))
        out += [("eig", v) for v in a["sufficient"]["lambda2"]]
        for key in ("mceip_mu", "mceip_lambda2"):
            sols = sorted(a[key]["solutions"], key=lambda x: x["value"])
            out.append(("n", len(sols)))
            out += [("val", x["value"]) for x in sols] + [("status", tuple(x["pattern"])) for x in sols]
    return out


@pytest.fixture(scope="module")
def serial(tmp_path_factory):
    d = tmp_path_factory.mktemp("mpi")
    (d / "s.yaml").write_text(SCENE)
    p = run_cli_here("run", str(d / "s.yaml"), "-o", str(d / "out1"), "-q")
    assert p.returncode == 0, p.stderr
    return d, json.loads((d / "out1" / "results.json").read_text())


@pytest.mark.mpi
@pytest.mark.slow
@pytest.mark.parametrize("ranks", [2, 3])
def test_same_numbers_on_any_number_of_ranks(serial, ranks):
    d, ref = serial
    p = run_cli("run", str(d / "s.yaml"), "-o", str(d / f"out{ranks}"), ranks=ranks)
    assert p.returncode == 0, p.stderr
    assert p.stdout.count("scene 'mpi-check'") == 1      # only rank 0 prints
    res = json.loads((d / f"out{ranks}" / "results.json").read_text())
    assert res["mpi_ranks"] == ranks
    a, b = _numbers(ref), _numbers(res)
    assert len(a) == len(b)
    for (ka, va), (kb, vb) in zip(a, b):
        assert ka == kb
        if ka in ("status", "n"):
            assert va == vb
        else:
            assert va == pytest.approx(vb, rel=1e-8, abs=1e-10 * 55 if ka == "r" else 0)
    # the study exercises the parallel MCP search: MCEIP-lambda^2 has a solution at the final state
    assert ref["states"][-1]["analyses"]["mceip_lambda2"]["solutions"]


ONE_RANK_FAILS = """
import sys
sys.path.insert(0, {root!r})
from mpi4py import MPI
import app.study.scheduler as distributed
from app.scene.schema import parse_scene
from app.study.run import study
comm = MPI.COMM_WORLD
real = distributed.state_mceip_mu
def failing(*a, **k):
    if comm.rank == 1 and k.get("replicated", True) is False:
        raise ValueError("a bug on rank 1")
    return real(*a, **k)
distributed.state_mceip_mu = failing
scene = parse_scene({{"name": "fails", "system": {{"type": "block", "nx": 16, "ny": 8}}, "mu": 1.1,
                     "analyses": ["mceip_mu"],
                     "settings": {{"mcp": {{"search_full_max": 3, "certify_enumerate_max": 3}}}}}})
try:
    study(scene, comm)
except Exception as err:
    print(f"rank {{comm.rank}} raised {{type(err).__name__}}: {{err}}", flush=True)
"""


@pytest.mark.mpi
def test_an_error_on_one_rank_is_raised_on_every_rank(tmp_path):
    """An unexpected error inside one rank's share of the MCEIP-mu jobs ends the study on both
    ranks (no rank left waiting in a collective): rank 1 raises its own, rank 0 one naming it."""
    script = tmp_path / "fails.py"
    script.write_text(ONE_RANK_FAILS.format(root=str(ROOT)))
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OMPI_MCA_rmaps_base_oversubscribe="1")
    p = subprocess.run(["mpirun", "--oversubscribe", "-n", "2", PY, str(script)], capture_output=True, text=True,
                       timeout=300, env=env)
    assert "rank 1 raised ValueError: a bug on rank 1" in p.stdout, p.stdout + p.stderr
    assert "rank 0 raised RuntimeError: MCEIP-mu failed on rank 1: ValueError: a bug on rank 1" in p.stdout, \
        p.stdout + p.stderr
