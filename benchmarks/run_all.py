"""The benchmark suite (`make bench`): what the app costs, and how it compares.

Prints the machine and versions, then every figure, and writes them to
output/bench/latest.json and output/bench/latest.md:

  scaling     per-stage times and peak memory of a block study against the number of DOFs
              (paper loading at growing crossed P1 meshes; one process per size), with fitted
              exponents t ~ DOFs^a, and the ratio of the study time to one sparse LU of K
              (the floor of the factor-once design)
  condensed   MCEIP-mu on the condensed slip-node pencil against the full-size MCP (same state,
              same search settings, same solutions?)
  enumeration the MCP search against exhaustive enumeration at s = 8..16 slip nodes
  certify     proven MCEIP-mu (onset and every mu <= cap) at s = 8..120 against exhaustive
              enumeration where it runs, with the search's recall (benchmarks/certify_bench.py)
  soundness   MCEIP-mu provers on 10,000 random pencils (s = 1-10, zero-node pairs, near-degenerate
              ones) against exhaustive enumeration with exact re-checks: false proofs (must be 0),
              not proven, ill-conditioned, unknown truth; onset proof time of dense random pencils at
              s = 10, 20, 30, ... (benchmarks/soundness.py)
  quadratic   the quadratic MCEIP-mu branch and bound (curved obstacles) on 300 random pencils
              (s = 1-10) against the exhaustive exact per-support proof: false proofs (must be 0),
              agreement, both times (benchmarks/soundness_quadratic.py)
  siconos     the app's contact increments and MCEIP-mu MCP runs against Siconos numerics
              (fc2d solvers, NCP Newton solvers) on the same problems (skipped with the reason
              when python3-siconos is not installed)
  tolerances  the refinement quantities and time against the SNES, SLEPc, acceptance and
              classification tolerances (benchmarks/tolerance_study.py)
  mpi         mpirun -n 2 against one process on the largest scaling case
  speed       issue 14: the default study (outputs off, forms compiled) against its floor (LU of K
              + W + loading path + the dense condensed eigenproblems), answers against the reference
              answers of the original code path, what pictures add; the 100k-DOF study (crossed P1
              224 x 112, MCEIP-mu at every distinct classification, sufficient condition at the final
              state) serial and on 2 ranks, with each stage's share
  targets     the paper study under 5 s serial (forms compiled); a 100k-DOF block study under 60 s;
              the four default analyses at 100k DOFs under 60 s on 1 rank and at 10^6 (708 x 354)
              under 5 minutes on 2 ranks, every MCEIP-mu onset proven (issue 33; --no-million skips
              the 10^6 run)

    .venv/bin/python benchmarks/run_all.py [--quick] [--only scaling,siconos,...]

Not part of the timed tests. --quick runs small sizes only (a smoke test, about a minute).
"""
from __future__ import annotations

import argparse
import json
import math
import os
import pathlib
import platform
import subprocess
import sys
import time

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402
from mpi4py import MPI  # noqa: E402
from petsc4py import PETSc  # noqa: E402

PY = sys.executable
SECTIONS = ("speed", "scaling", "condensed", "enumeration", "certify", "soundness", "quadratic", "siconos",
            "tolerances", "mpi", "targets")
ENV = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
           OMPI_MCA_rmaps_base_oversubscribe="1", PYTHONPATH=str(ROOT))


def say(*a) -> None:
    print(*a, flush=True)


# -- machine ---------------------------------------------------------------------------------------
def machine() -> dict:
    import dolfinx
    import gmsh
    import mpi4py
    import scipy
    import slepc4py
    cpu = platform.processor() or ""
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    try:
        mem = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") / 2 ** 30
    except (ValueError, OSError):
        mem = float("nan")
    try:
        ompi = subprocess.run(["mpirun", "--version"], capture_output=True, text=True, env=ENV).stdout.split("\n")[0]
    except OSError:
        ompi = "mpirun not found"
    sic = _siconos_version()
    load = os.getloadavg()
    info = {"cpu": cpu, "cores": os.cpu_count(), "memory_GiB": round(mem, 1), "load_avg_1min": round(load[0], 2),
            "os": platform.platform(), "python": platform.python_version(), "numpy": np.__version__,
            "scipy": scipy.__version__, "PETSc": ".".join(map(str, PETSc.Sys.getVersion())),
            "petsc4py": __import__("petsc4py").__version__, "slepc4py": slepc4py.__version__,
            "DOLFINx": dolfinx.__version__, "gmsh": gmsh.__version__, "mpi4py": mpi4py.__version__,
            "MPI": ompi, "siconos": sic or "not installed"}
    return info


def _siconos_version() -> str | None:
    try:
        import siconos.numerics  # noqa: F401
    except ImportError:
        return None
    try:
        out = subprocess.run(["dpkg-query", "-W", "-f=${Version}", "python3-siconos"], capture_output=True, text=True)
        if out.stdout.strip():
            return "Debian python3-siconos " + out.stdout.strip()
    except OSError:
        pass
    import importlib.metadata as md
    try:
        return md.version("siconos")
    except Exception:
        return "installed"


def fit_exponent(x, y) -> float | None:
    pts = [(math.log(a), math.log(b)) for a, b in zip(x, y) if a and b and a > 0 and b > 0]
    if len(pts) < 2:
        return None
    X, Y = zip(*pts)
    return float(np.polyfit(X, Y, 1)[0])


# -- scaling ---------------------------------------------------------------------------------------
def level_run(nx: int, ranks: int = 1, final_only: bool = True, timeout: float = 3600) -> dict:
    cmd = [PY, str(ROOT / "benchmarks" / "level_run.py"), "--nx", str(nx)]
    if final_only:
        cmd.append("--final-only")
    if ranks > 1:
        cmd = ["mpirun", "--oversubscribe", "-n", str(ranks), *cmd]
    env = dict(ENV, OPENBLAS_NUM_THREADS="1") if ranks > 1 else ENV
    out = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, env=env, cwd=ROOT)
    lines = [l for l in out.stdout.splitlines() if l.startswith("{")]
    if out.returncode != 0 or not lines:
        raise RuntimeError(f"level_run nx={nx} ranks={ranks} failed: {out.stderr[-2000:]}")
    return json.loads(lines[-1])


STAGE_KEYS = ("t_mesh_assembly", "t_factor_W", "t_loading", "t_mceip_mu", "t_sufficient")


def section_scaling(sizes: list[int]) -> dict:
    say(f"\n== scaling: paper loading on crossed P1 meshes nx = {sizes} (one process each; final-state "
        f"MCEIP-mu and sufficient condition at mu = 2) ==")
    say(f"{'nx':>5} {'DOFs':>8} {'nodes':>5} {'states':>6} {'total[s]':>9} {'mesh+asm':>9} {'K+W':>8} "
        f"{'loading':>8} {'MCEIP-mu':>9} {'suff.':>7} {'LU(K)[s]':>9} {'total/LU':>9} {'peak MB':>8}")
    runs = []
    for nx in sizes:
        r = level_run(nx)
        row = r["row"]
        runs.append(r)
        ratio = r["wall_s"] / r["factor_s"] if r["factor_s"] else float("nan")
        say(f"{nx:>5} {row['dofs']:>8} {row['contact_nodes']:>5} {row['states']:>6} {r['wall_s']:>9.2f} "
            + " ".join(f"{row[k]:>8.2f}" for k in STAGE_KEYS)
            + f" {r['factor_s']:>9.3f} {ratio:>9.0f} {r['peak_rss_mb']:>8.0f}")
    dofs = [r["row"]["dofs"] for r in runs]
    exps = {k: fit_exponent(dofs, [r["row"][k] for r in runs]) for k in STAGE_KEYS}
    exps["total"] = fit_exponent(dofs, [r["wall_s"] for r in runs])
    exps["LU(K)"] = fit_exponent(dofs, [r["factor_s"] for r in runs])
    exps["peak_memory"] = fit_exponent(dofs, [r["peak_rss_mb"] for r in runs])
    say("fitted exponents a in t ~ DOFs^a: " + ", ".join(f"{k} {v:.2f}" for k, v in exps.items() if v is not None))
    big = runs[-1]
    say(f"floor of the factor-once design: at {big['row']['dofs']} DOFs the study takes "
        f"{big['wall_s'] / big['factor_s']:.0f} x one sparse LU of K ({big['factor_s']:.3f} s); "
        f"K + W (LU and 2n = {2 * big['row']['contact_nodes']} solves) is {big['row']['t_factor_W']:.2f} s")
    return {"runs": runs, "exponents": exps}


# -- condensed vs full-size MCEIP-mu ---------------------------------------------------------------
def section_condensed(sizes: list[int]) -> dict:
    from app.analyses.runner import analyse_state
    from app.common.progress import Progress
    from app.common.stages import Stages
    from app.loading.classify import classify
    from app.systems.block.path import path as block_path
    from benchmarks.problems import block_scene
    say(f"\n== condensed slip-node pencil against the full-size MCP: MCEIP-mu at the final state, nx = {sizes} "
        f"(both with settings.mcp pattern_starts = false, pattern_eig_limit = 0: the same uniform starts and gap "
        f"search) ==")
    say(f"{'nx':>5} {'DOFs':>8} {'s':>4} {'full[s]':>9} {'condensed[s]':>13} {'ratio':>8} {'+W ratio':>9} "
        f"{'same solutions':>15}")
    out = []
    for nx in sizes:
        base = block_scene(nx, analyses=["mceip_mu"])
        st = Stages()
        system, states, _ = block_path(base, MPI.COMM_WORLD, st, Progress(enabled=False))
        t_w = next(r["seconds"] for r in st.as_list() if r["name"].startswith("factorise K"))
        cls = classify(states[-1], base.mu, base.settings.classify_rtol)
        n_dofs = system.n_dofs
        res, times = {}, {}
        for method in ("condensed", "full"):
            sc = base.model_copy(update={"settings": base.settings.model_copy(update={
                "mceip_mu_method": method,
                "mcp": base.settings.mcp.model_copy(update={"pattern_starts": False, "pattern_eig_limit": 0})})})
            t0 = time.perf_counter()
            res[method] = analyse_state(system, cls, sc)["mceip_mu"]
            times[method] = time.perf_counter() - t0
        system.destroy()
        vc = [s["value"] for s in res["condensed"]["solutions"]]
        vf = [s["value"] for s in res["full"]["solutions"]]
        same = len(vc) == len(vf) and all(abs(a - b) <= 1e-6 * max(1, abs(a)) for a, b in zip(vc, vf)) and all(
            np.allclose(a["x_Ts"], b["x_Ts"], atol=1e-6) for a, b in zip(res["condensed"]["solutions"],
                                                                          res["full"]["solutions"]))
        ratio = times["full"] / times["condensed"]
        ratio_w = times["full"] / (times["condensed"] + t_w)
        say(f"{nx:>5} {n_dofs:>8} {len(cls.slip):>4} {times['full']:>9.2f} {times['condensed']:>13.3f} "
            f"{ratio:>8.1f} {ratio_w:>9.1f} {str(same) + ' ' + str([round(v, 6) for v in vc]):>15}")
        out.append({"nx": nx, "dofs": n_dofs, "s": len(cls.slip), "full_s": times["full"],
                    "condensed_s": times["condensed"], "W_s": t_w, "ratio": ratio, "ratio_incl_W": ratio_w,
                    "same_solutions": bool(same), "values_condensed": vc, "values_full": vf})
    say("(+W ratio: the condensed time charged with the whole factorisation and W, which the study pays once)")
    return {"runs": out}


# -- MCP search against enumeration ----------------------------------------------------------------
def _match(sol: dict, ref: dict) -> bool:
    return (abs(sol["value"] - ref["value"]) <= 1e-6 * max(1.0, abs(ref["value"]))
            and sol["pattern"] == ref["pattern"] and np.allclose(sol["x_Ts"], ref["x_Ts"], atol=1e-5))


def section_enumeration(s_values: list[int], seed: int = 3) -> dict:
    from app.analyses.enumerate import enumerate_mceip
    from app.analyses.pencils.reduced import condensed_mu_pencil
    from app.analyses.pencils.state import seq_aij
    from app.analyses.snes_vi.search import search_mceip
    from app.common.stages import Stages
    from app.loading.classify import classify
    from app.scene.schema import McpSettings
    from app.systems.discrete import random_contact_problem
    from benchmarks.problems import block_problems
    say(f"\n== MCP search against exhaustive enumeration, MCEIP-mu, s = {s_values[0]}..{s_values[-1]} slip nodes "
        f"(block: first state of the paper path with s slip nodes, paper mesh; random: SPD systems) ==")
    say(f"{'s':>3} {'problem':>8} {'enumerated':>10} {'found':>6} {'spurious':>8} {'t_search[s]':>11} "
        f"{'t_enum[s]':>10} {'enum/search':>11}")
    probs = block_problems(nx=20)
    by_s: dict = {}
    for p in probs.pencils:
        by_s.setdefault(p.A0.shape[0], p)
    rng = np.random.default_rng(seed)
    rows = []
    for s in s_values:
        cases = []
        if s in by_s:
            cases.append(("block", by_s[s].A0, by_s[s].A1))
        mu = float(rng.uniform(0.5, 3.0))
        system, state = random_contact_problem(rng, s + 2, 4, s, 0, mu, MPI.COMM_WORLD, Stages())
        A0, A1 = condensed_mu_pencil(system.contact_schur(), classify(state, mu))
        system.destroy()
        cases.append(("random", A0, A1))
        for kind, A0, A1 in cases:
            t0 = time.perf_counter()
            ref = enumerate_mceip(A0, A1, np.arange(s), max_slip=24)
            te = time.perf_counter() - t0
            M0, M1 = seq_aij(A0), seq_aij(A1)
            t0 = time.perf_counter()
            rep = search_mceip(M0, M1, np.arange(s), "mu", McpSettings())
            ts = time.perf_counter() - t0
            M0.destroy()
            M1.destroy()
            found = [x.as_dict() for x in rep.solutions]
            hit = sum(any(_match(f, r) for f in found) for r in ref)
            spurious = sum(not any(_match(f, r) for r in ref) for f in found)
            say(f"{s:>3} {kind:>8} {len(ref):>10} {hit:>6} {spurious:>8} {ts:>11.3f} {te:>10.3f} {te / ts:>11.1f}")
            rows.append({"s": s, "problem": kind, "enumerated": len(ref), "found": hit, "spurious": spurious,
                         "t_search": ts, "t_enum": te, "ratio": te / ts})
    tot = sum(r["enumerated"] for r in rows)
    hit = sum(r["found"] for r in rows)
    say(f"total: {hit} of {tot} enumerated solutions found, {sum(r['spurious'] for r in rows)} spurious; "
        f"enumeration/search time ratio {rows[0]['ratio']:.1f} at s = {rows[0]['s']} -> {rows[-1]['ratio']:.1f} "
        f"at s = {rows[-1]['s']}")
    return {"rows": rows, "found": hit, "enumerated": tot}


# -- Siconos ---------------------------------------------------------------------------------------
class _quiet_c_output:
    """Silence what C code prints on stdout/stderr (Siconos' LU messages) inside the block."""

    def __enter__(self):
        sys.stdout.flush()
        sys.stderr.flush()
        self.saved = (os.dup(1), os.dup(2))
        null = os.open(os.devnull, os.O_WRONLY)
        os.dup2(null, 1)
        os.dup2(null, 2)
        os.close(null)
        return self

    def __exit__(self, *exc):
        os.dup2(self.saved[0], 1)
        os.dup2(self.saved[1], 2)
        for fd in self.saved:
            os.close(fd)
        return False


def _fc2d_violation(M, q, r, mu) -> float:
    u = M @ r + q
    p, rt, g, d = r[0::2], r[1::2], u[0::2], u[1::2]
    sr = max(float(np.max(np.abs(r))), 1e-300)
    su = max(float(np.max(np.abs(u))), float(np.max(np.abs(q))), 1e-300)   # displacement scale of the load
    slide = np.abs(d) > 1e-9 * su
    v = [max(0.0, -np.min(p)) / sr, max(0.0, -np.min(g)) / su, np.max(np.abs(p * g)) / (sr * su),
         max(0.0, float(np.max(np.abs(rt) - mu * p))) / sr,
         float(np.max(np.where(slide, np.abs(rt + mu * p * np.sign(d)), 0.0))) / sr]
    return float(max(v))


def section_siconos(sizes: list[int]) -> dict:
    try:
        import siconos.numerics as sn
        sn.numerics_set_verbose(0)
    except ImportError:
        msg = ("skipped: Siconos numerics is not installed (Debian package python3-siconos, about 22 MB with "
               "its dependencies; `make bench` installs it through scripts/setup_bench.sh)")
        say("\n== Siconos ==\n" + msg)
        return {"skipped": msg}
    from app.analyses.enumerate import enumerate_mceip
    from app.analyses.pencils.state import seq_aij
    from app.analyses.snes_vi.search import RSLS, SSLS, BorderedMcp, search_mceip
    from app.loading.contact import FrictionalContact
    from app.scene.schema import McpSettings
    from benchmarks.problems import block_problems
    out: dict = {"version": _siconos_version(), "contact": [], "mceip_mu": {}}
    say(f"\n== Siconos numerics {out['version']} on the same problems ==")
    say("contact increments of the paper's path as 2D frictional contact problems (u = M r + q, Coulomb):")
    say(f"{'nx':>4} {'nodes':>5} {'solver':>10} {'success':>9} {'agree':>9} {'max diff (ok)':>14} {'time[s]':>8} "
        f"{'app[s]':>8} {'app/solver':>10}")
    settings = McpSettings()
    pencil_sets = []
    for nx in sizes:
        P = block_problems(nx=nx)
        if nx == 20:
            pencil_sets.append(P.pencils)
        n = P.n_contact
        perm = np.empty(2 * n, dtype=int)
        perm[0::2], perm[1::2] = 2 * np.arange(n) + 1, 2 * np.arange(n)
        D = np.tile([-1.0, 1.0], n)
        M = D[:, None] * P.W[np.ix_(perm, perm)] * D[None, :]
        mu = P.scene.mu
        app = FrictionalContact(P.Kc, mu)
        t0 = time.perf_counter()
        app_r = []
        for inc in P.increments:
            res = app.solve(inc.u0, inc.u_T_prev, inc.g_prev)
            app_r.append(np.ravel(np.column_stack([-res.r_N, res.r_T])))
        t_app = time.perf_counter() - t0
        app.destroy()
        for sid, name in ((sn.SICONOS_FRICTION_2D_NSGS, "fc2d NSGS"), (sn.SICONOS_FRICTION_2D_LEMKE, "fc2d Lemke"),
                          (sn.SICONOS_FRICTION_2D_CPG, "fc2d CPG")):
            ok, agree, diffs, tt = 0, 0, [], 0.0
            for inc, ra in zip(P.increments, app_r):
                prev = np.zeros(2 * n)
                prev[1::2] = inc.u_T_prev
                q = D * inc.u0[perm] - prev
                fc = sn.FrictionContactProblem(2, n, M, q, np.full(n, mu))
                so = sn.SolverOptions(sid)
                so.dparam[sn.SICONOS_DPARAM_TOL] = 1e-12
                so.iparam[sn.SICONOS_IPARAM_MAX_ITER] = 100000
                r, u = np.zeros(2 * n), np.zeros(2 * n)
                t0 = time.perf_counter()
                with _quiet_c_output():
                    info = sn.fc2d_driver(fc, r, u, so)
                tt += time.perf_counter() - t0
                good = info == 0 and np.all(np.isfinite(r)) and _fc2d_violation(M, q, r, mu) <= 1e-8
                ok += bool(good)
                diff = float(np.max(np.abs(r - ra)) / max(np.max(np.abs(ra)), 1e-300))
                agree += bool(good and diff <= 1e-6)
                if good:
                    diffs.append(diff)
            worst = max(diffs, default=float("nan"))
            say(f"{nx:>4} {n:>5} {name:>10} {ok:>4}/{len(P.increments):<4} {agree:>4}/{len(P.increments):<4} "
                f"{worst:>14.2e} {tt:>8.3f} {t_app:>8.3f} {t_app / tt:>10.2f}")
            out["contact"].append({"nx": nx, "nodes": n, "solver": name, "success": ok, "agree": agree,
                                   "problems": len(P.increments), "max_rel_diff_ok": worst, "time_s": tt,
                                   "app_s": t_app, "app_over_solver": t_app / tt})
        say(f"{'':>4} {'':>5} {'app':>10} {len(P.increments):>4}/{len(P.increments):<4} {'':>9} {'(reference)':>14} "
            f"{t_app:>8.3f}   (SNES VI vinewtonrsls, projection form, checked to 1e-9)")
    say("(success: the solver reports convergence and the solution satisfies Signorini-Coulomb to 1e-8; agree: "
        "and it equals the app's reactions to 1e-6)")

    # MCEIP-mu: the condensed MCPs of the paper path, NCP form z = (x_Ts, mu) >= 0.
    say("MCEIP-mu condensed MCPs of the paper path (20x10 mesh, every distinct classification with slip "
        "nodes), as NCPs z = (x_Ts, mu) >= 0, F = ((A0 + mu A1) x, e^T x - 1), from the app's uniform starts "
        f"t0 in {settings.starts}:")
    pencils = pencil_sets[0]
    runs = {"app vinewtonrsls": [0, 0, 0.0], "app vinewtonssls": [0, 0, 0.0], "NCP Newton FB": [0, 0, 0.0],
            "NCP Newton min-FB": [0, 0, 0.0]}
    found = {k: 0 for k in (*runs, "app search")}
    total_ref, t_search = 0, 0.0
    for p in pencils:
        s = p.A0.shape[0]
        ref = enumerate_mceip(p.A0, p.A1, np.arange(s), max_slip=24)
        total_ref += len(ref)
        alpha = float(np.max(np.abs(np.diag(p.A0))))
        B0, B1 = p.A0 / alpha, p.A1 / alpha
        M0, M1 = seq_aij(p.A0), seq_aij(p.A1)
        t0 = time.perf_counter()
        rep = search_mceip(M0, M1, np.arange(s), "mu", settings)
        t_search += time.perf_counter() - t0
        found["app search"] += sum(any(_match(x.as_dict(), r) for x in rep.solutions) for r in ref)
        S0, S1 = seq_aij(B0), seq_aij(B1)
        op = BorderedMcp(S0, S1, np.arange(s))
        values: dict = {k: [] for k in runs}

        def record(name, x, t, dt):
            runs[name][1] += 1
            runs[name][2] += dt
            sol = op.check(np.asarray(x, dtype=float), float(t), settings.accept_tol)
            if sol is not None:
                runs[name][0] += 1
                values[name].append(sol.as_dict())

        for t0v in settings.starts:
            x0 = np.ones(s) / s
            tic = time.perf_counter()
            x, t, reason, its = op.solve(RSLS, x0, t0v, 0.0, 1.0, PETSc.INFINITY, settings, x_full=x0.copy())
            record("app vinewtonrsls", x, t, time.perf_counter() - tic)
            tic = time.perf_counter()
            x, t, reason, its = op.solve(SSLS, x0, t0v, 0.0, 1.0, PETSc.INFINITY, settings, x_full=x0.copy())
            record("app vinewtonssls", x, t, time.perf_counter() - tic)

            def F(nn, z, Fz):
                Fz[:s] = (B0 + z[s] * B1) @ z[:s]
                Fz[s] = z[:s].sum() - 1.0

            def J(nn, z, nab):
                nab[:s, :s] = B0 + z[s] * B1
                nab[:s, s] = B1 @ z[:s]
                nab[s, :s] = 1.0
                nab[s, s] = 0.0

            for sid, name in ((sn.SICONOS_NCP_NEWTON_FB_FBLSA, "NCP Newton FB"),
                              (sn.SICONOS_NCP_NEWTON_MIN_FBLSA, "NCP Newton min-FB")):
                ncp = sn.NCP(s + 1, F, J)
                so = sn.SolverOptions(sid)
                so.dparam[sn.SICONOS_DPARAM_TOL] = 1e-12
                so.iparam[sn.SICONOS_IPARAM_MAX_ITER] = settings.max_it
                z, w = np.concatenate([x0, [t0v]]), np.zeros(s + 1)
                tic = time.perf_counter()
                with _quiet_c_output():
                    sn.ncp_driver(ncp, z, w, so)
                record(name, z[:s], z[s], time.perf_counter() - tic)
        for name in runs:
            found[name] += sum(any(_match(v, r) for v in values[name]) for r in ref)
        op.destroy()
        for m in (M0, M1, S0, S1):
            m.destroy()
    say(f"{'method':>20} {'runs':>5} {'success':>8} {'distinct solutions found':>25} {'time[s]':>8} {'ms/run':>7}")
    for name, (ok, n_runs, tt) in runs.items():
        say(f"{name:>20} {n_runs:>5} {ok:>8} {found[name]:>14} of {total_ref:<8} {tt:>8.3f} {1e3 * tt / n_runs:>7.2f}")
    say(f"{'app search (all)':>20} {'':>5} {'':>8} {found['app search']:>14} of {total_ref:<8} {t_search:>8.3f}"
        f"   (starts, pattern neighbourhoods, gap search)")
    say("(NCP_PATHSEARCH is left out: Siconos 4.4 aborts the process on these problems; PATH itself is not in "
        "Debian's build)")
    a = runs["app vinewtonrsls"]
    b = runs["NCP Newton FB"]
    out["mceip_mu"] = {"runs": {k: {"success": v[0], "runs": v[1], "time_s": v[2], "found": found[k]}
                                for k, v in runs.items()},
                       "app_search": {"found": found["app search"], "time_s": t_search},
                       "enumerated": total_ref, "per_run_time_ratio_app_over_fb": (a[2] / a[1]) / (b[2] / b[1])}
    return out


# -- MPI -------------------------------------------------------------------------------------------
def section_mpi(nx: int, serial: dict | None) -> dict:
    say(f"\n== mpirun -n 2 against one process: nx = {nx} (final-state study) ==")
    if serial is None:
        serial = level_run(nx)
    par = level_run(nx, ranks=2)
    same = all(abs((serial["row"][k] or 0) - (par["row"][k] or 0)) <= 1e-6 * max(1.0, abs(serial["row"][k] or 0))
               for k in ("final_mu", "lambda2", "depth", "tangential_resultant"))
    say(f"{'':>10} {'total[s]':>9} " + " ".join(f"{k[2:]:>12}" for k in STAGE_KEYS) + f" {'peak MB':>8}")
    for label, r in (("1 rank", serial), ("2 ranks", par)):
        say(f"{label:>10} {r['wall_s']:>9.2f} " + " ".join(f"{r['row'][k]:>12.2f}" for k in STAGE_KEYS)
            + f" {r['peak_rss_mb']:>8.0f}")
    say(f"speed-up 2 ranks / 1 rank: {serial['wall_s'] / par['wall_s']:.2f}; same quantities: {same} "
        f"(machine load {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores)")
    return {"serial": serial, "parallel": par, "speedup": serial["wall_s"] / par["wall_s"], "same": same}



# -- speed (issue 14) ------------------------------------------------------------------------------
def _shares(stages: list[dict], wall: float) -> str:
    top = sorted(stages, key=lambda r: -r["seconds"])[:6]
    return ", ".join(f"{r['name']} {r['seconds']:.2f} s ({100 * r['seconds'] / wall:.0f} %)" for r in top)


def _big_run(nx: int, ranks: int, timeout: float) -> dict:
    """benchmarks/big_study.py in its own process(es); a run stopped by ``timeout`` reports how far it got."""
    cmd = [PY, str(ROOT / "benchmarks" / "big_study.py"), "--nx", str(nx)]
    env = ENV
    if ranks > 1:   # one core per rank, one BLAS thread per rank; a waiting rank yields its core
        cmd = ["mpirun", "--oversubscribe", "--bind-to", "core", "-n", str(ranks), *cmd]
        env = dict(ENV, OPENBLAS_NUM_THREADS="1", OMPI_MCA_mpi_yield_when_idle="1")
    t0 = time.perf_counter()
    try:
        out = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, env=env, cwd=ROOT)
        stdout, finished = out.stdout, out.returncode == 0
    except subprocess.TimeoutExpired as err:
        stdout = err.stdout.decode() if isinstance(err.stdout, bytes) else (err.stdout or "")
        finished = False
    lines = [json.loads(l) for l in stdout.splitlines() if l.startswith("{")]
    done = [l for l in lines if l.get("done")]
    progress = [l for l in lines if "classification" in l]
    return {"ranks": ranks, "finished": bool(done) and finished, "elapsed_s": time.perf_counter() - t0,
            "result": done[-1] if done else None,
            "classifications_done": progress[-1]["classification"] if progress else 0,
            "last_slip": progress[-1]["slip"] if progress else None}


def section_speed(quick: bool, big_timeout: float) -> dict:
    import scipy.linalg
    from threadpoolctl import threadpool_limits

    from app.analyses.pencils.reduced import condensed_mu_pencil
    from app.loading.classify import classify
    from app.scene.schema import default_scene_path, load_scene
    from app.study.run import study
    sys.path.insert(0, str(ROOT / "tests"))
    from test_default_answers import REFERENCE, differences
    say("\n== speed (issue 14): machine shared with other jobs, load "
        f"{os.getloadavg()[0]:.1f} on {os.cpu_count()} cores; times are noisy, ratios are within one run ==")
    scene = load_scene(default_scene_path())
    scene = scene.model_copy(update={"outputs": None})
    study(scene, MPI.COMM_WORLD)                          # forms compiled, mesh cached
    t0 = time.perf_counter()
    res = study(scene, MPI.COMM_WORLD).to_dict()
    wall = time.perf_counter() - t0
    stages = {r["name"]: r["seconds"] for r in res["stages"]}
    bad: list[str] = differences(json.loads(REFERENCE.read_text()), res) if REFERENCE.exists() else []

    # floor: LU of K + W, the loading path, and one dense eigen-decomposition per distinct classification
    floor_captured: dict = {}

    def capture(system, states, cache):
        Sc = system.contact_schur()
        t = time.perf_counter()
        with threadpool_limits(1, user_api="blas"):
            for key, (first, _) in cache.items():
                cls = classify(states[first], scene.mu, scene.settings.classify_rtol)
                if len(cls.slip):
                    A0, A1 = condensed_mu_pencil(Sc, cls)
                    scipy.linalg.eig(A0, -A1)
        floor_captured["dense"] = time.perf_counter() - t
        return None

    res2 = study(scene.model_copy(update={"analyses": []}), MPI.COMM_WORLD, inspect=capture).to_dict()
    st2 = {r["name"]: r["seconds"] for r in res2["stages"]}
    floor = (st2.get("factorise K, contact flexibility", 0.0) + st2.get("quasi-static loading", 0.0)
             + floor_captured.get("dense", 0.0))
    say(f"default study, outputs off, forms compiled: {wall:.2f} s serial (target 1.5 s: "
        f"{'met' if wall <= 1.5 else 'NOT met'}); floor (LU of K + W {st2.get('factorise K, contact flexibility', 0):.3f} s, "
        f"loading path {st2.get('quasi-static loading', 0):.3f} s, dense condensed eigenproblems "
        f"{floor_captured.get('dense', 0):.3f} s) = {floor:.2f} s: study / floor = {wall / floor:.1f}x")
    say(f"  stage shares: {_shares(res['stages'], wall)}")
    say("  answers vs the original code path (tests/data/default_study_answers.json): "
        + ("identical (every value to 1e-8, every pattern and classification)" if REFERENCE.exists() and not bad
           else f"{len(bad)} differences, first {bad[:3]}"))

    # pictures: the CLI with the default scene's outputs against the same scene with outputs off,
    # alternated 3 times (the fastest of each: the machine is shared)
    import tempfile
    with tempfile.TemporaryDirectory() as tmp:
        off = pathlib.Path(tmp) / "off.yaml"
        off.write_text(default_scene_path().read_text().split("\noutputs:")[0] + "\n")
        times: dict = {"off": [], "on": []}
        for rep in range(3):
            for label, path in (("off", off), ("on", default_scene_path())):
                t = time.perf_counter()
                subprocess.run([PY, "-m", "app", "run", "-q", "-o", str(pathlib.Path(tmp) / f"{label}{rep}"), str(path)],
                               env=ENV, cwd=ROOT, capture_output=True)
                times[label].append(time.perf_counter() - t)
        on_stages = json.loads((pathlib.Path(tmp) / "on2" / "results.json").read_text()).get("stages", [])
    pics = min(times["on"]) - min(times["off"])
    say(f"pictures (plots, report, ParaView files, screenshots): CLI run {min(times['on']):.1f} s with outputs, "
        f"{min(times['off']):.1f} s without (fastest of 3 each): they add {pics:.1f} s (target 2 s: "
        f"{'met' if pics <= 2 else 'NOT met'}); picture stages of the last run: "
        + ", ".join(f"{r['name']} {r['seconds']:.2f} s" for r in on_stages
                    if r["name"].startswith(("fields", "plots", "screenshots", "report")))
        + " (plots and screenshots are drawn at the same time, each stage is its process's drawing time)")

    nx = 40 if quick else 224
    dofs = 2 * ((nx + 1) * (nx // 2 + 1) + nx * (nx // 2))
    big = {}
    for ranks in (1, 2):
        r = _big_run(nx, ranks, big_timeout)
        big[ranks] = r
        if r["result"]:
            w = r["result"]["wall_s"]
            say(f"{dofs}-DOF study (crossed P1 {nx} x {nx // 2}, MCEIP-mu at every distinct classification, "
                f"sufficient condition at the final state), {ranks} rank(s): {w:.1f} s "
                f"({r['result']['classifications']} classifications, {r['result']['states']} states; target 60 s "
                f"serial: {'met' if w <= 60 else 'NOT met'}); final-state mu {r['result']['final_mu']}")
            say(f"  stage shares: {_shares(r['result']['stages'], w)}; sufficient at the final state "
                f"{r['result']['final_sufficient']['seconds']:.1f} s")
        else:
            say(f"{dofs}-DOF study, {ranks} rank(s): did NOT finish in {big_timeout:.0f} s "
                f"({r['classifications_done']} classifications analysed, the last with s = {r['last_slip']})")
    if all(big[k]["result"] for k in (1, 2)):
        say(f"  2 ranks / 1 rank speed-up: {big[1]['result']['wall_s'] / big[2]['result']['wall_s']:.2f}")
    return {"default_s": wall, "default_stages": stages, "floor_s": floor, "answers_identical": not bad,
            "pictures_s": pics, "big": big, "big_dofs": dofs}

# -- targets ---------------------------------------------------------------------------------------
def default_at_scale(nx: int, ranks: int, timeout: float) -> dict:
    """The paper's scene with its four default analyses (outputs off) on a crossed P1 ``nx x nx/2``
    mesh through the CLI, on ``ranks`` processes: the wall time and whether every distinct
    classification's MCEIP-mu onset is proven; ``wall_s`` None when stopped at ``timeout``."""
    import tempfile

    import yaml

    from app.scene.schema import default_scene_path
    data = yaml.safe_load(default_scene_path().read_text())
    data.pop("outputs", None)
    data["system"].update(nx=nx, ny=nx // 2)
    with tempfile.TemporaryDirectory() as tmp:
        scene = pathlib.Path(tmp) / "scene.yaml"
        scene.write_text(yaml.safe_dump(data))
        cmd = [PY, "-m", "app", "run", str(scene), "-o", str(pathlib.Path(tmp) / "out"), "-q"]
        if ranks > 1:
            cmd = ["mpirun", "-n", str(ranks), *cmd]
        t0 = time.perf_counter()
        try:
            proc = subprocess.run(cmd, env=ENV, cwd=ROOT, capture_output=True, text=True, timeout=timeout)
        except subprocess.TimeoutExpired:
            return {"nx": nx, "ranks": ranks, "wall_s": None, "onsets_proven": None}
        wall = time.perf_counter() - t0
        if proc.returncode != 0:
            return {"nx": nx, "ranks": ranks, "wall_s": None, "error": proc.stderr.strip()[-300:]}
        res = json.loads((pathlib.Path(tmp) / "out" / "results.json").read_text())
    mu = [s["analyses"]["mceip_mu"] for s in res["states"]
          if s.get("analyses_shared_with") is None and isinstance((s.get("analyses") or {}).get("mceip_mu"), dict)]
    proven = sum(bool(a.get("certified") or (a.get("onset") or {}).get("proven")) for a in mu)
    return {"nx": nx, "ranks": ranks, "wall_s": wall, "dofs": None, "classifications": len(mu),
            "onsets_proven": proven, "stages": {r["name"]: r["seconds"] for r in res["stages"]}}


def section_targets(big: dict | None, big_nx: int, million_nx: int | None = None) -> dict:
    from app.scene.schema import default_scene_path, load_scene
    from app.study.run import study
    say("\n== targets ==")
    scene = load_scene(default_scene_path())
    study(scene, MPI.COMM_WORLD)                     # compiles the forms
    t0 = time.perf_counter()
    res = study(scene, MPI.COMM_WORLD).to_dict()
    paper = time.perf_counter() - t0
    stages = {r["name"]: r["seconds"] for r in res["stages"]}
    say(f"paper study (20x10 mesh, analyses {', '.join(scene.analyses)}; {len(res['states'])} states, "
        f"{res['distinct_classifications']} classifications): {paper:.2f} s serial (target 5 s: "
        f"{'met' if paper < 5 else 'NOT met'}); largest stages: "
        + ", ".join(f"{k} {v:.2f} s" for k, v in sorted(stages.items(), key=lambda kv: -kv[1])[:3]))
    mu_only = scene.model_copy(update={"analyses": ["mceip_mu"]})
    t0 = time.perf_counter()
    study(mu_only, MPI.COMM_WORLD)
    t_mu = time.perf_counter() - t0
    say(f"paper study with MCEIP-mu only: {t_mu:.2f} s")
    if big is None:
        big = level_run(big_nx)
    t_big = big["wall_s"]
    say(f"{big['row']['dofs']}-DOF block study (crossed {big['row']['nx']}x{big['row']['ny']}, "
        f"{big['row']['contact_nodes']} contact nodes, {big['row']['states']} states; loading path, classification, "
        f"MCEIP-mu and sufficient condition at the final state): {t_big:.1f} s (target 60 s: "
        f"{'met' if t_big < 60 else 'NOT met'})")
    out = {"paper_s": paper, "paper_stages": stages, "paper_mceip_mu_only_s": t_mu, "big_dofs": big["row"]["dofs"],
           "big_s": t_big, "default_at_scale": []}
    # issue 33: the four default analyses at 100k DOFs within 60 s on 1 rank, at 10^6 within 5 min on 2
    for nx, ranks, target in ((big_nx, 1, 60.0), (million_nx, 2, 300.0)):
        if nx is None:
            continue
        r = default_at_scale(nx, ranks, timeout=max(4 * target, 600.0))
        r["target_s"] = target
        out["default_at_scale"].append(r)
        wall = "stopped at the time limit" if r["wall_s"] is None else f"{r['wall_s']:.1f} s"
        met = r["wall_s"] is not None and r["wall_s"] < target and r["onsets_proven"] == r["classifications"]
        say(f"default study (four analyses) at {nx} x {nx // 2} on {ranks} rank(s): {wall}, "
            f"{r.get('onsets_proven')}/{r.get('classifications')} MCEIP-mu onsets proven "
            f"(target {target:.0f} s, every onset proven: {'met' if met else 'NOT met'})")
    return out


# -- main ------------------------------------------------------------------------------------------
def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="small sizes only (smoke test)")
    ap.add_argument("--only", default=",".join(SECTIONS), help=f"comma-separated subset of {','.join(SECTIONS)}")
    ap.add_argument("--out", default=str(ROOT / "output" / "bench"))
    ap.add_argument("--no-million", action="store_true",
                    help="skip the 10^6-DOF default study on 2 ranks of the targets section (up to 20 min)")
    ap.add_argument("--big-timeout", type=float, default=900.0,
                    help="time limit of each 100k-DOF run of the speed section (s)")
    args = ap.parse_args()
    only = [s.strip() for s in args.only.split(",") if s.strip()]
    bad = [s for s in only if s not in SECTIONS]
    if bad:
        ap.error(f"unknown section(s) {bad}; allowed: {', '.join(SECTIONS)}")
    if args.quick:
        sizes, cond, s_values, sic, big_nx, tol_nx = [10, 20, 40], [20, 40], [8, 9, 10], [20], 40, [10]
    else:
        sizes, cond, s_values, sic, big_nx, tol_nx = ([20, 40, 80, 160, 224], [20, 80, 160], list(range(8, 17)),
                                                      [20, 80], 224, [20, 40])
    t_start = time.perf_counter()
    info = machine()
    say("machine: " + "; ".join(f"{k} {v}" for k, v in info.items()))
    results: dict = {"machine": info, "quick": args.quick, "date": time.strftime("%Y-%m-%d %H:%M:%S")}
    if "speed" in only:
        results["speed"] = section_speed(args.quick, args.big_timeout)
    if "scaling" in only:
        results["scaling"] = section_scaling(sizes)
    if "condensed" in only:
        results["condensed"] = section_condensed(cond)
    if "enumeration" in only:
        results["enumeration"] = section_enumeration(s_values)
    if "certify" in only:
        from benchmarks.certify_bench import section_certify
        results["certify"] = section_certify([8, 12] if args.quick else [8, 12, 16, 20, 30, 60, 120],
                                             enum_max=12 if args.quick else 16)
    if "soundness" in only:
        from benchmarks.soundness import section_dense, section_soundness
        results["soundness"] = {"random": section_soundness(300 if args.quick else 10_000),
                                "dense": section_dense(s_values=[10, 20, 30] if args.quick else None)}
    if "quadratic" in only:
        from benchmarks.soundness_quadratic import section_quadratic
        results["quadratic"] = section_quadratic(60 if args.quick else 300, say=say)
    if "siconos" in only:
        results["siconos"] = section_siconos(sic)
    if "tolerances" in only:
        from benchmarks.tolerance_study import run as tolerance_run
        results["tolerances"] = tolerance_run(tol_nx, say=say)
    runs = {r["row"]["nx"]: r for r in results.get("scaling", {}).get("runs", [])}
    if "mpi" in only:
        results["mpi"] = section_mpi(big_nx, runs.get(big_nx))
    if "targets" in only:
        results["targets"] = section_targets(runs.get(big_nx), big_nx,
                                             None if (args.quick or args.no_million) else 708)
    results["wall_s"] = time.perf_counter() - t_start
    say(f"\nbenchmark suite: {results['wall_s']:.0f} s")
    say(summary(results))
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "latest.json").write_text(json.dumps(results, indent=1, default=str))
    (out / "latest.md").write_text(summary(results) + "\n")
    say(f"written: {out / 'latest.json'}, {out / 'latest.md'}")


def summary(res: dict) -> str:
    """The ratios on one page (also output/bench/latest.md)."""
    m = res["machine"]
    lines = ["== summary ==",
             f"machine: {m['cpu']}, {m['cores']} cores, {m['memory_GiB']} GiB (load {m['load_avg_1min']}); "
             f"DOLFINx {m['DOLFINx']}, PETSc {m['PETSc']}, SLEPc {m['slepc4py']}, gmsh {m['gmsh']}, "
             f"numpy {m['numpy']}, Python {m['python']}, {m['MPI']}, Siconos {m['siconos']}"]
    if "speed" in res:
        sp = res["speed"]
        lines.append(f"default study {sp['default_s']:.2f} s (target 1.5 s), floor {sp['floor_s']:.2f} s, answers "
                     f"identical: {sp['answers_identical']}; pictures add {sp['pictures_s']:.1f} s (target 2 s)")
        for k, r in sp["big"].items():
            lines.append(f"big study ({sp['big_dofs']} DOFs), {k} rank(s): " + (f"{r['result']['wall_s']:.1f} s" if r["result"] else
                         f"not finished in the time limit ({r['classifications_done']} classifications)"))
    if "scaling" in res:
        runs = res["scaling"]["runs"]
        e = res["scaling"]["exponents"]
        big = runs[-1]
        lines.append(f"scaling ({runs[0]['row']['dofs']}..{big['row']['dofs']} DOFs): t ~ DOFs^a with a = "
                     + ", ".join(f"{k} {v:.2f}" for k, v in e.items() if v is not None))
        lines.append(f"study / one LU of K at {big['row']['dofs']} DOFs: {big['wall_s'] / big['factor_s']:.0f}x "
                     f"({big['wall_s']:.1f} s vs {big['factor_s']:.3f} s)")
    if "condensed" in res:
        for r in res["condensed"]["runs"]:
            lines.append(f"condensed vs full-size MCEIP-mu at {r['dofs']} DOFs (s = {r['s']}): {r['ratio']:.1f}x "
                         f"({r['ratio_incl_W']:.1f}x charging W), same solutions: {r['same_solutions']}")
    if "enumeration" in res:
        rows = res["enumeration"]["rows"]
        lines.append(f"MCP search vs enumeration, s = {rows[0]['s']}..{rows[-1]['s']}: found "
                     f"{res['enumeration']['found']} of {res['enumeration']['enumerated']}, time ratio enum/search "
                     + ", ".join(f"s={r['s']} {r['ratio']:.1f}" for r in rows if r["problem"] == "random"))
    if "certify" in res:
        rows = res["certify"]["rows"]
        lines.append("certified MCEIP-mu: " + ", ".join(
            f"s={r['s']} {r['kind']} {r['t_certify']:.2f} s ({r['status']})" for r in rows)
            + f"; largest s within a minute: {res['certify']['largest_s_within_60s']}")
    if "soundness" in res:
        r, d = res["soundness"]["random"], res["soundness"]["dense"]
        c = r["counts"]
        lines.append(f"soundness ({r['prover']}): {c['pencils']} random pencils, FALSE PROOFS {c['false_proofs']}, "
                     f"proven onset {c['proven_onset']}, proven all {c['proven_all']}, not proven {c['not_proven']}, "
                     f"ill-conditioned {c['ill_conditioned']}, unknown truth {c['unknown_truth']}; dense random "
                     f"pencils: largest s with the onset proven within 60 s: {d['largest_s']}")
    if "quadratic" in res:
        from benchmarks.soundness_quadratic import describe
        lines.append(describe(res["quadratic"]))
    if "siconos" in res:
        s = res["siconos"]
        if "skipped" in s:
            lines.append("Siconos: " + s["skipped"])
        else:
            for c in s["contact"]:
                lines.append(f"contact increments, {c['nodes']} nodes, Siconos {c['solver']}: success "
                             f"{c['success']}/{c['problems']}, same solution as the app {c['agree']}/{c['problems']}, "
                             f"app time / Siconos time = {c['app_over_solver']:.2f}")
            mm = s["mceip_mu"]
            lines.append("MCEIP-mu MCPs from the same starts (success / runs, solutions found of "
                         f"{mm['enumerated']} enumerated): " + "; ".join(
                             f"{k} {v['success']}/{v['runs']}, {v['found']}" for k, v in mm["runs"].items())
                         + f"; app search {mm['app_search']['found']}; per-run time app/FB "
                         f"{mm['per_run_time_ratio_app_over_fb']:.2f}")
    if "tolerances" in res:
        rows = res["tolerances"]
        base = {r["nx"]: r for r in rows if r["setting"] == "default"}
        worst = {}
        for r in rows:
            if r["setting"] == "default":
                continue
            b = base[r["nx"]]
            ch = [abs(r[q] - b[q]) / max(abs(b[q]), 1e-300) for q in ("final_mu", "lambda2", "depth")
                  if r[q] is not None and b[q] is not None]
            key = f"{r['setting']}={r['value']}"
            worst[key] = max(worst.get(key, 0.0), max(ch, default=0.0))
        lines.append("tolerances (largest relative change of final mu, lambda^2, depth): "
                     + ", ".join(f"{k} {v:.1e}" for k, v in worst.items()))
    if "mpi" in res:
        r = res["mpi"]
        lines.append(f"mpirun -n 2 vs 1 at {r['serial']['row']['dofs']} DOFs: speed-up {r['speedup']:.2f}, "
                     f"same quantities: {r['same']}")
    if "targets" in res:
        t = res["targets"]
        lines.append(f"paper study serial: {t['paper_s']:.2f} s (target 5 s: {'met' if t['paper_s'] < 5 else 'NOT met'}); "
                     f"MCEIP-mu only {t['paper_mceip_mu_only_s']:.2f} s")
        lines.append(f"{t['big_dofs']}-DOF block study (final-state analyses): {t['big_s']:.1f} s "
                     f"(target 60 s: {'met' if t['big_s'] < 60 else 'NOT met'})")
        for r in t.get("default_at_scale", []):
            wall = "stopped at the time limit" if r["wall_s"] is None else f"{r['wall_s']:.1f} s"
            lines.append(f"default study (four analyses) {r['nx']} x {r['nx'] // 2} on {r['ranks']} rank(s): {wall}, "
                         f"onsets proven {r.get('onsets_proven')}/{r.get('classifications')} (target {r['target_s']:.0f} s)")
    return "\n".join(lines)


if __name__ == "__main__":
    main()
