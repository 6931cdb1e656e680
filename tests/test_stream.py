"""The loading path walked on rank 0 and streamed to the other ranks (app/study/stream.py): the
other ranks prove the classifications rank 0 has passed while it walks. The answers must be those
of one rank, on every rank; a path that fails on rank 0 fails on every rank."""
import os
import subprocess

import pytest
from conftest import PY, ROOT

from app.study.scheduler import Chains, _chains

SCRIPT = """
import json, sys
sys.path.insert(0, {root!r})
sys.path.insert(0, {bench!r})
from mpi4py import MPI
import app.study.stream as stream
from app.scene.schema import parse_scene
from app.study.run import study
from app.io.document import from_document, json_clean
from compare_results import answers, compare
comm = MPI.COMM_WORLD
real = stream.walk
used = []
def walk(*a, **k):
    used.append(True)
    return real(*a, **k)
stream.walk = walk
scene = parse_scene({{"name": "streamed", "system": {{"type": "block", "nx": 16, "ny": 8}}, "mu": 1.1,
                     "analyses": ["mceip_mu"],
                     "settings": {settings}}})
doc = lambda r: from_document(json_clean(r.to_json()))
mine = answers(doc(study(scene, comm)))
every = comm.gather(mine)
if comm.rank == 0:
    stream.walk = real
    alone = answers(doc(study(scene, MPI.COMM_SELF)))
    differ = [compare(alone, a, 1e-8) for a in every]     # the rank count changes W in its last digits
    new = [s for s in alone["states"] if s["shared_with"] is None]
    print(json.dumps({{"streamed": used, "differences": [sum(map(len, d.values())) for d in differ],
                      "classifications": len(new), "with_zero": sum(1 for s in new if "e" in s["status"])}}),
          flush=True)
"""

FAILS = """
import sys
sys.path.insert(0, {root!r})
from mpi4py import MPI
import app.systems.block.path as block
from app.common.errors import UnreachableLoad
from app.scene.schema import parse_scene
from app.study.run import study
comm = MPI.COMM_WORLD
real = block.walker
def walker(scene, comm, stages):
    system, walk = real(scene, comm, stages)
    def failing(progress, on_state=None):
        def send(state):
            on_state(state)
            if state.index == 14:
                raise UnreachableLoad("the drag cannot go on", key="loading.tangential_max")
        return walk(progress, send)
    return system, failing
block.walker = walker
scene = parse_scene({{"name": "fails", "system": {{"type": "block", "nx": 16, "ny": 8}}, "mu": 1.1,
                     "analyses": ["mceip_mu"]}})
try:
    study(scene, comm)
except UnreachableLoad as err:
    print(f"rank {{comm.rank}} raised UnreachableLoad({{err.key}}): {{err}}", flush=True)
"""


def _mpirun(tmp_path, text: str, ranks: int, **fields) -> subprocess.CompletedProcess:
    script = tmp_path / "script.py"
    script.write_text(text.format(root=str(ROOT), bench=str(ROOT / "benchmarks"), **fields))
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OMPI_MCA_rmaps_base_oversubscribe="1")
    return subprocess.run(["mpirun", "--oversubscribe", "-n", str(ranks), PY, str(script)], capture_output=True,
                          text=True, timeout=300, env=env)


#: chains of several jobs (warm starts); zero-reaction nodes (a wide classification tolerance):
#: their states are analysed by every rank together after the path
CASES = {"chains": '{"mcp": {"search_full_max": 3, "warm_chain": 3}}', "zero nodes": '{"classify_rtol": 0.03}'}


@pytest.mark.mpi
@pytest.mark.parametrize("ranks,case", [(2, "chains"), (3, "chains"), (2, "zero nodes"), (3, "zero nodes")])
def test_streamed_answers_are_those_of_one_rank_on_every_rank(tmp_path, ranks, case):
    """MCEIP-mu alone on the block: the path is streamed (every rank enters it) and every rank's
    answers (values, modes, patterns, classifications, certificate statuses) equal a one-rank run's (values to
    1e-8, as every comparison across rank counts)."""
    import json
    p = _mpirun(tmp_path, SCRIPT, ranks, settings=CASES[case])
    lines = [ln for ln in p.stdout.splitlines() if ln.startswith("{")]
    assert lines, p.stdout + p.stderr
    got = json.loads(lines[-1])
    assert got["streamed"] == [True]                 # rank 0's own record
    assert got["classifications"] > 10
    if case == "zero nodes":
        assert got["with_zero"] > 5                  # postponed during the path
    assert got["differences"] == [0] * ranks, got


@pytest.mark.mpi
def test_a_path_that_fails_on_rank_0_fails_on_every_rank(tmp_path):
    """An UnreachableLoad raised in rank 0's walk, after some states were streamed, is raised on
    every rank with its message and key (no rank left waiting)."""
    p = _mpirun(tmp_path, FAILS, 2)
    for rank in (0, 1):
        assert f"rank {rank} raised UnreachableLoad(loading.tangential_max): the drag cannot go on" in p.stdout, \
            p.stdout + p.stderr


def test_chains_grow_as_jobs_arrive():
    """:class:`Chains` fed one job at a time gives the chains of the whole list, and ``complete``
    never counts a chain that a later job could still extend."""
    s = [1, 2, 50, 60, 70, 80, 3, 90, 91, 2]
    chains = Chains(3, 40)
    seen = []
    for k, v in enumerate(s):
        chains.add(v)
        seen.append(chains.complete)
        final = _chains(s, 3, 40)
        for c in range(chains.complete):            # a complete chain is final already
            assert chains.chains[c] == final[c]
    assert seen == [1, 2, 2, 2, 3, 3, 5, 5, 5, 7]
    chains.close()
    assert chains.complete == len(chains.chains) == len(_chains(s, 3, 40))
    assert chains.chains == [[0], [1], [2, 3, 4], [5], [6], [7, 8], [9]]
