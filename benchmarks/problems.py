"""Problems taken from a block study, for the benchmarks: the condensed MCEIP-mu pencils of
every distinct classification, and the quasi-static contact increments of the path.

    from benchmarks.problems import block_problems
    probs = block_problems(nx=20)        # the paper's mesh
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from mpi4py import MPI

from app.analyses.pencils.reduced import UnsupportedState, condensed_mu_pencil
from app.common.progress import Progress
from app.common.stages import Stages
from app.loading.classify import classify
from app.scene.schema import Scene, parse_scene


@dataclass
class MuPencil:
    """Condensed MCEIP-mu pencil ``(A0 + mu A1) x = y`` of one classification (s x s)."""
    state: int
    label: str
    A0: np.ndarray
    A1: np.ndarray


@dataclass
class Increment:
    """One contact increment: ``u_c = u0 + W r``, previous tangential displacement and gap."""
    state: int
    u0: np.ndarray
    u_T_prev: np.ndarray
    g_prev: np.ndarray
    u_T: np.ndarray              # the app's solution (paper axes)
    u_N: np.ndarray
    r_T: np.ndarray
    r_N: np.ndarray


@dataclass
class BlockProblems:
    scene: Scene
    W: np.ndarray                # contact flexibility, paper axes, (T_0, N_0, T_1, ...)
    Kc: np.ndarray               # W^-1
    pencils: list[MuPencil]
    increments: list[Increment]
    n_dofs: int
    n_contact: int


def block_scene(nx: int = 20, ny: int | None = None, pattern: str = "crossed", degree: int = 1,
                analyses=("mceip_mu",), mu: float = 1.1, mesh_size: float | None = None, **loading) -> Scene:
    data = {"name": f"bench-{pattern}-{nx}", "mu": mu, "analyses": list(analyses),
            "system": {"type": "block", "nx": nx, "ny": ny or max(nx // 2, 1), "pattern": pattern, "degree": degree}}
    if mesh_size is not None:
        data["system"]["mesh_size"] = mesh_size
    if loading:
        data["loading"] = loading
    return parse_scene(data)


def block_problems(nx: int = 20, pattern: str = "crossed", degree: int = 1, comm=MPI.COMM_WORLD,
                   mesh_size: float | None = None, **loading) -> BlockProblems:
    """Run the block's loading path and collect its MCEIP-mu pencils and contact increments."""
    from app.systems.block.path import path as block_path
    scene = block_scene(nx, pattern=pattern, degree=degree, mesh_size=mesh_size, **loading)
    stages = Stages()
    system, states, _ = block_path(scene, comm, stages, Progress(enabled=False))
    flex = system.flexibility
    Sc = system.contact_schur()
    pencils, seen = [], set()
    for st in states:
        cls = classify(st, scene.mu, scene.settings.classify_rtol)
        if cls.key in seen or len(cls.slip) == 0:
            continue
        seen.add(cls.key)
        try:
            A0, A1 = condensed_mu_pencil(Sc, cls)
        except UnsupportedState:
            continue
        pencils.append(MuPencil(state=st.index, label=cls.label(), A0=A0, A1=A1))
    n = len(system.nodes)
    increments = []
    uT, g = np.zeros(n), np.zeros(n)
    for st in states:
        load = st.load
        u0 = flex.u0x * load["u_x"] + flex.u0y * load["u_y"]
        increments.append(Increment(state=st.index, u0=u0, u_T_prev=uT, g_prev=g, u_T=st.u_T, u_N=st.u_N,
                                    r_T=st.r_T, r_N=st.r_N))
        uT, g = st.u_T, -st.u_N
    out = BlockProblems(scene=scene, W=flex.W.copy(), Kc=Sc.copy(), pencils=pencils, increments=increments,
                        n_dofs=system.n_dofs, n_contact=n)
    system.destroy()
    return out
