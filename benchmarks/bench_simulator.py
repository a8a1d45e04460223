#!/usr/bin/env python3
"""Speed of the sheet simulator: real-time factor, scaling with N, memory, profile, MuJoCo.

Measures, on this machine:

* ``rtf_n25``: simulated seconds per wall second of the default cell's 120 s
  two-step cycle (movement 4, ``run_movement(p, 4)``) with N = 25 masses,
  on ONE core (the process is pinned to one CPU and BLAS/OpenMP are limited to one thread).  The
  settle (the inertial pre-sag, cached per cell in ``simulation._SETTLED``) is
  timed separately, with the cache cleared; the cycle is timed with the settle
  cached.  Medians of ``--repeats`` runs.
* ``scaling``: the same cycle for N = 25 ... 1000: wall seconds per simulated
  second (and CPU seconds), steps, Newton iterations, energy evaluations and
  banded solves per step (the compiled kernel's counters, ``SheetModel.stats``),
  settle time.  Sizes run in a process pool (``--jobs``, a fresh process per
  size, so two sizes share the two cores).
* ``peak_memory_mb``: for N = 25 and the largest N, the peak RSS during the
  timed cycles (VmHWM reset before them; the interpreter with numpy and scipy
  loaded included) and the tracemalloc peak of one more cycle (N = 25; the
  largest N with ``--trace-largest``).
* ``profile``: cProfile of the N = 25 cycle (settle cached): top functions by
  own and cumulative time (the compiled kernel is one call), the kernel's work
  per step, and per-call costs measured without the profiler (``micro``).
* ``effects``: the default cell's cycle (N = 63) with each effect of
  :mod:`rheo_shaping.sheet.effects` alone at the top of its realistic range, timed
  interleaved with the nominal cycle: the ratio of the two.
* ``cold_start``: ``rheo-shaping simulate --json`` in a fresh process, first
  with an empty compile cache (a temporary ``NUMBA_CACHE_DIR``), then with the
  cache it filled.
* ``mujoco_ratio``: MuJoCo's wall time over ours on a shared elastic problem,
  both run until their largest node error against the exact discrete
  equilibrium (``analytic.elastic_chain_equilibrium``) is <= 1e-6 m.  Chain
  N = 25, span 0.10 m, drop -0.08 m, L0 = 0.15 m, 0.3125 kg/m, EA = 9.5 N,
  links k_i = EA/L_i, ends fixed, no contact, no plastic flow, straight start
  at rest (links slack).  Ours: ``SheetModel`` with c2 = inf links, one
  quasi-static step of 1e3 s (``dynamic=False``; the inertia term m/dt^2
  is then a ~1e-9 N/m proximal term).  MuJoCo: an MJCF model built here, each
  mass a body with two slide joints (x, z) so it moves in the plane, a point
  mass; each link a spatial tendon between sites with ``stiffness = k_i`` and
  the deadband ``springlength = "0 L_i"`` (no force when shorter than L_i,
  k_i (l - L_i) when longer: a linear tension-only spring, exactly our link);
  joint damping (implicit in the ``implicitfast`` integrator) so it settles;
  contacts and constraints disabled.  Damping and time step are picked from a
  grid as the combination that reaches 1e-6 m in the fewest steps (MuJoCo's
  best case); the timed run is ``mj_step(m, d, nstep)`` (the loop in C).
  ``mujoco_ratio = mujoco_wall / ours_wall`` (> 1: ours is faster).

Wall times include whatever else runs on the machine: the load average is
recorded, and CPU times (``time.process_time``) are given beside them.

``--json`` prints one JSON object (progress bars go to stderr); ``--quick``
runs fewer repeats, sizes up to 200 and a smaller MuJoCo grid; ``--no-effects``,
``--no-cold-start`` and ``--no-mujoco`` skip those parts.
"""
from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMEXPR_NUM_THREADS"):
    os.environ.setdefault(_var, "1")        # one thread per process, set before numpy loads

import argparse  # noqa: E402
import collections  # noqa: E402
import contextlib  # noqa: E402
import cProfile  # noqa: E402
import io  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import multiprocessing  # noqa: E402
import platform  # noqa: E402
import pstats  # noqa: E402
import resource  # noqa: E402
import statistics  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
import timeit  # noqa: E402
import tracemalloc  # noqa: E402
from concurrent.futures import ProcessPoolExecutor, as_completed  # noqa: E402
from dataclasses import asdict, replace  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import scipy  # noqa: E402

try:
    import rheo_shaping  # noqa: F401
except ImportError:                                   # run from a source tree without installing
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import rheo_shaping.sheet.simulation as simulation  # noqa: E402
from rheo_shaping.sheet.analytic import elastic_chain_equilibrium  # noqa: E402
from rheo_shaping.params.cell import CellParams  # noqa: E402
from rheo_shaping.planning.movement import movement_plan  # noqa: E402
from rheo_shaping.sheet.chain import ChainConstants, SheetModel  # noqa: E402
from rheo_shaping.sheet.simulation import Simulation, run_scenario  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _machine import cpu_name  # noqa: E402

SIZES = (25, 50, 63, 100, 200, 400, 1000)
MB = 1024.0 * 1024.0


# ---------------------------------------------------------------------- machine
def machine_info() -> dict:
    cpu = cpu_name()
    try:
        import mujoco
        mj = mujoco.__version__
    except ImportError:
        mj = None
    return {"platform": platform.platform(), "machine": platform.machine(), "cpu": cpu,
            "cpus": os.cpu_count(), "python": platform.python_version(), "numpy": np.__version__,
            "scipy": scipy.__version__, "mujoco": mj,
            "threads": {v: os.environ.get(v) for v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS")}}


@contextlib.contextmanager
def one_core():
    """Pin this process to one CPU (restored afterwards)."""
    if not hasattr(os, "sched_getaffinity"):
        yield None
        return
    before = os.sched_getaffinity(0)
    cpu = max(before)
    os.sched_setaffinity(0, {cpu})
    try:
        yield cpu
    finally:
        os.sched_setaffinity(0, before)


# ------------------------------------------------------------------------ cycle
def cycle(n: int):
    """The default cell with ``n`` masses and its movement-4 plan (read fresh)."""
    p = CellParams()
    p = replace(p, sheet=replace(p.sheet, n_masses=int(n)))
    return p, movement_plan(p, 4)


def time_settle(p, plan) -> tuple[float, float]:
    """(wall, CPU) [s] of a cold ``Simulation`` (chain + settle), the settle cache cleared."""
    simulation._SETTLED.clear()
    c0, t0 = time.process_time(), time.perf_counter()
    Simulation(p, tool_start=plan.position(0.0))
    return time.perf_counter() - t0, time.process_time() - c0


def time_cycle(p, plan, t_end=None) -> tuple[float, float, float, object]:
    """(wall of the whole run_scenario call, wall of its stepping loop, CPU of the call [s],
    result), with the settle cached."""
    c0, t0 = time.process_time(), time.perf_counter()
    r = run_scenario(p, plan, t_end=t_end)
    return time.perf_counter() - t0, r.wall_time_s, time.process_time() - c0, r


def _proc_status_mb(field: str) -> float | None:
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith(field + ":"):
                return float(line.split()[1]) / 1024.0
    except OSError:
        pass
    return None


def _reset_peak_rss() -> bool:
    """Reset this process's VmHWM to its current RSS (Linux >= 4.0)."""
    try:
        with open("/proc/self/clear_refs", "w") as f:
            f.write("5")
        return True
    except OSError:
        return False


@contextlib.contextmanager
def counting(*given):
    """Count the solver's work during a run: the kernel's counters (SheetModel.stats) of every
    model made inside the block and of the ``given`` models, summed."""
    from rheo_shaping.sheet import kernel as K
    c = collections.Counter()
    models: list = [(m, m.stats.copy()) for m in given]
    init = SheetModel.__init__

    def tracked(self, *a, **k):
        init(self, *a, **k)
        models.append((self, self.stats.copy()))

    SheetModel.__init__ = tracked
    try:
        yield c
    finally:
        SheetModel.__init__ = init
        total = sum((m.stats - s0 for m, s0 in models), np.zeros(5, dtype=np.int64))
        c["newton"] = int(total[K.ST_NEWTON])
        c["evaluate"] = int(total[K.ST_EVAL])
        c["banded_solve"] = int(total[K.ST_SOLVE])
        c["substeps"] = int(total[K.ST_SUBSTEPS])
        c["failed_minimise"] = int(total[K.ST_FAILED])


def cell_fingerprint() -> str:
    """Short hash of the default cell as this process reads it (other engineers edit params.py)."""
    import hashlib
    return hashlib.sha1(repr(asdict(CellParams())).encode()).hexdigest()[:12]


def size_job(n: int, repeats: int, t_end: float | None, trace: bool = False) -> dict:
    """One size in a fresh process: cold settle, timed cycles (the first one counting the
    solver's work: wrappers add < 1 %), optionally a tracemalloc'd cycle."""
    p, plan = cycle(n)
    t_sim = p.movement.process_time if t_end is None else float(t_end)
    settle_wall, settle_cpu = time_settle(p, plan)
    rss_before = _proc_status_mb("VmRSS")
    hwm_reset = _reset_peak_rss()
    walls, loops, cpus = [], [], []
    for k in range(repeats):
        with (counting() if k == 0 else contextlib.nullcontext()) as cnt:
            w, loop, cpu, r = time_cycle(p, plan, t_end)
        if k == 0:
            c = cnt.copy()
        walls.append(w)
        loops.append(loop)
        cpus.append(cpu)
    hwm = _proc_status_mb("VmHWM")
    peak = None
    if trace:
        tracemalloc.start()
        run_scenario(p, plan, t_end=t_end)
        peak = tracemalloc.get_traced_memory()[1] / MB
        tracemalloc.stop()
    steps = int(r.t.size - 1)
    wall = statistics.median(walls)
    return {
        "n": n, "sim_s": t_sim, "window_shortened": t_end is not None,
        "steps": steps, "wall_s": wall, "wall_s_min": min(walls),
        "wall_s_loop": statistics.median(loops),
        "cpu_s": statistics.median(cpus), "repeats": repeats,
        "wall_s_per_sim_s": wall / t_sim, "cpu_s_per_sim_s": statistics.median(cpus) / t_sim,
        "rtf": t_sim / wall, "settle_wall_s": settle_wall, "settle_cpu_s": settle_cpu,
        "newton_iterations_mean": c["newton"] / steps,
        "evaluations_per_step": c["evaluate"] / steps,
        "banded_solves_per_step": c["banded_solve"] / steps,
        "retried_steps": c["substeps"] - steps, "failed_newton": c["failed_minimise"],
        "F_max_N": r.F_max, "delta_m": r.delta,
        "tracemalloc_peak_mb": peak,
        "rss_before_cycles_mb": rss_before,
        "peak_rss_during_cycles_mb": hwm if hwm_reset else None,
        "ru_maxrss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
        "cell_fingerprint": cell_fingerprint(),
    }


# ---------------------------------------------------------------------- profile
def _label(key) -> str:
    fname, line, func = key
    if fname == "~":
        return func
    parts = Path(fname).parts
    short = "/".join(parts[-2:]) if "rheo_shaping" in parts else Path(fname).name
    return f"{short}:{line}({func})"


def profile_cycle(n: int = 25, top: int = 12) -> dict:
    p, plan = cycle(n)
    Simulation(p, tool_start=plan.position(0.0))          # settle cached
    pr = cProfile.Profile()
    pr.enable()
    r = run_scenario(p, plan)
    pr.disable()
    st = pstats.Stats(pr, stream=io.StringIO())
    total = st.total_tt
    rows = [(k, v[1], v[2], v[3]) for k, v in st.stats.items()]   # key, ncalls, tottime, cumtime

    def table(idx):
        out = []
        for k, nc, tt, ct in sorted(rows, key=lambda r: -r[idx])[:top]:
            out.append({"function": _label(k), "calls": nc, "own_s": round(tt, 5),
                        "cum_s": round(ct, 5),
                        "own_pct": round(100 * tt / total, 1),
                        "cum_pct": round(100 * ct / total, 1)})
        return out

    def calls(func, file_part=""):
        return sum(nc for k, nc, _, _ in rows if k[2] == func and file_part in k[0])

    def own(pred):
        return sum(tt for k, _, tt, _ in rows if pred(k))

    steps = int(r.t.size - 1)
    kernel = own(lambda k: k[0] == "~" and "advance_path" in k[2]) + \
        own(lambda k: k[0].endswith("dispatcher.py"))
    kernel = max(kernel, sum(ct for k, _, _, ct in rows if k[2] == "run_path"))
    schedule = sum(ct for k, _, _, ct in rows if k[2] == "schedule")
    with counting() as cnt:
        run_scenario(p, plan)
    return {
        "n": n, "profiled_wall_s": total, "steps": steps,
        "by_own_time": table(2), "by_cumulative_time": table(3),
        "calls_per_step": {
            "Newton iterations": cnt["newton"] / steps,
            "energy evaluations": cnt["evaluate"] / steps,
            "banded solves": cnt["banded_solve"] / steps,
            "kernel calls (run_path)": calls("run_path") / steps,
        },
        "own_time_pct": {
            "compiled kernel (SheetModel.run_path)": round(100 * kernel / total, 1),
            "step schedule (tool path sampling)": round(100 * schedule / total, 1),
        },
    }


def micro(n: int = 25, number: int = 2000) -> dict:
    """Per-call CPU costs [us] without the profiler, on the N = 25 cycle's state one step
    before the tool pushes hardest: one step as a Python call, its compiled parts."""
    try:
        from rheo_shaping.sheet import kernel as K
        p, plan = cycle(n)
        r = run_scenario(p, plan)
        k = max(int(np.argmax(np.hypot(r.tool_force[:, 0], r.tool_force[:, 1]))) - 1, 0)
        t = float(r.t[k])
        sim = Simulation(p, tool_start=plan.position(0.0))
        if t > 0.0:
            sim.advance_to(t, plan.position(t), tool_at=plan.position)
        m, s = sim.model, sim.state
        dt = p.solver.dt
        tool = plan.position(min(t + dt, float(r.t[-1])))
        f = lambda fn: 1e6 * min(timeit.repeat(  # noqa: E731
            fn, timer=time.process_time, number=number, repeat=3)) / number
        shapes = {ob.name: ob for ob in m.obstacles}
        dts, tools = np.full(20, dt / 20), np.repeat(tool[None], 20, axis=0)
        x = s.x.copy()
        res = {
            "state_t_s": t,
            "contacts": {ob.name: int(np.count_nonzero(np.abs(s.contact[i]).sum(1)))
                         for i, ob in enumerate(m.obstacles)},
            "step_us": f(lambda: m.step(s, dt, tool)),
            "run_path_per_step_us": f(lambda: m.run_path(s, dts, tools)) / 20,
            "cake_signed_distance_us": f(lambda: shapes["cake"].shape.signed_distance(x)),
            "tool_signed_distance_us": f(lambda: shapes["tool"].shape.signed_distance(x, tool)),
            "band_cholesky_us": f(lambda: K.band_cholesky(*_spd_band(2 * n))),
            "tool_path_sample_us": f(lambda: plan.position(t)),
            "state_copy_us": f(lambda: s.copy()),
        }
        return {k: (round(v, 2) if isinstance(v, float) else v) for k, v in res.items()}
    except Exception as exc:  # pragma: no cover - internals changed
        return {"error": f"{type(exc).__name__}: {exc}"}


_BANDS: dict = {}


def _spd_band(m: int, kd: int = 3):
    """A banded SPD test matrix (m unknowns, half bandwidth kd) and its factor buffer."""
    if m not in _BANDS:
        band = np.zeros((m, 5))
        band[:, 0] = 4.0
        band[:-1, 1] = band[:-2, 2] = band[:-3, 3] = -0.5
        _BANDS[m] = (band, kd, np.zeros((m, 6)))
    return _BANDS[m]


# ----------------------------------------------------------------------- MuJoCo
def elastic_problem(n=25, span=0.10, drop=-0.08, length=0.15, mu=0.3125, ea=9.5, g=9.81):
    L = np.full(n + 1, length / (n + 1))
    c = ChainConstants(anchor_top=np.array([0.0, 0.0]), anchor_bottom=np.array([span, drop]),
                       rest_length=L, k1=ea / L, c1=np.zeros(n + 1), c2=np.full(n + 1, np.inf),
                       mass=np.full(n, mu * length / (n + 1)), radius=2e-3, gravity=g)
    exact = elastic_chain_equilibrium(
        c.anchor_top, c.anchor_bottom, c.rest_length, c.k1, c.mass, g)
    s = np.linspace(0.0, 1.0, n + 2)[1:-1, None]
    x0 = c.anchor_top + s * (c.anchor_bottom - c.anchor_top)
    return c, exact, x0


def _err(x, exact) -> float:
    return float(np.max(np.hypot(x[:, 0] - exact[:, 0], x[:, 1] - exact[:, 1])))


def ours_elastic_runner(c, x0, schedule, dynamic=False, force_tol=1e-9, max_newton=50):
    """A function running our solver from the straight start through ``schedule`` [s]."""
    model = SheetModel(c, [], force_tol=force_tol, max_newton=max_newton)

    def run():
        st = model.initial_state(x0)
        for dt in schedule:
            st = model.step(st, dt, dynamic=dynamic)
        return st
    run.model = model
    return run


def _timed(fn) -> tuple[float, float]:
    c0, t0 = time.process_time(), time.perf_counter()
    fn()
    return time.perf_counter() - t0, time.process_time() - c0


def ours_elastic(c, exact, x0, schedule, repeats=15, **kw) -> dict:
    run = ours_elastic_runner(c, x0, schedule, **kw)
    with counting(run.model) as cnt:
        st = run()
    t = [_timed(run) for _ in range(repeats)]
    return {"schedule_s": list(schedule), "error_m": _err(st.x, exact),
            "wall_s": statistics.median(w for w, _ in t),
            "cpu_s": statistics.median(cp for _, cp in t),
            "newton_iterations": cnt["newton"], "evaluations": cnt["evaluate"]}


def mujoco_xml(c, x0, dt: float, damping: float, integrator: str = "implicitfast") -> str:
    n = c.n_masses
    f = lambda v: f"{float(v):.17g}"  # noqa: E731
    bodies = []
    for i in range(n):
        bodies.append(
            f'<body name="m{i}" pos="{f(x0[i, 0])} 0 {f(x0[i, 1])}">'
            f'<joint name="x{i}" type="slide" axis="1 0 0" damping="{f(damping)}"/>'
            f'<joint name="z{i}" type="slide" axis="0 0 1" damping="{f(damping)}"/>'
            f'<inertial pos="0 0 0" mass="{f(c.mass[i])}" diaginertia="1e-9 1e-9 1e-9"/>'
            f'<site name="s{i}"/></body>')
    sites = ["A"] + [f"s{i}" for i in range(n)] + ["B"]
    tendons = "".join(
        f'<spatial stiffness="{f(c.k1[i])}" springlength="0 {f(c.rest_length[i])}">'
        f'<site site="{sites[i]}"/><site site="{sites[i + 1]}"/></spatial>' for i in range(n + 1))
    a, b = c.anchor_top, c.anchor_bottom
    return (f'<mujoco model="elastic_chain"><option timestep="{f(dt)}" gravity="0 0 '
            f'{f(-c.gravity)}" '
            f'integrator="{integrator}"><flag contact="disable" constraint="disable"/></option>'
            f'<worldbody><site name="A" pos="{f(a[0])} 0 {f(a[1])}"/>'
            f'<site name="B" pos="{f(b[0])} 0 {f(b[1])}"/>{"".join(bodies)}</worldbody>'
            f'<tendon>{tendons}</tendon></mujoco>')


def mujoco_steps_to(mujoco, model, x0, exact, tol, cap) -> tuple[int | None, float]:
    """Steps after which the node error stays <= tol (None: not within cap), final error."""
    d = mujoco.MjData(model)
    n = x0.shape[0]
    last_bad = 0
    for k in range(1, cap + 1):
        mujoco.mj_step(model, d)
        e = _err(x0 + d.qpos.reshape(n, 2), exact)
        if not math.isfinite(e) or e > 1.0:
            return None, e
        if e > tol:
            last_bad = k
        elif e < 1e-3 * tol:
            return last_bad + 1, e
    return (last_bad + 1 if last_bad < cap else None), e


def mujoco_compare(quick: bool = False, tol: float = 1e-6, repeats: int = 21) -> dict:
    try:
        import mujoco
    except ImportError:
        return {"error": "mujoco not installed"}
    c, exact, x0 = elastic_problem()
    # MuJoCo: grid over time step and joint damping; fewest steps to tol wins
    dts = (5e-4, 1e-3, 1.5e-3) if quick else (2.5e-4, 5e-4, 1e-3, 1.25e-3, 1.5e-3)
    damps = (0.02, 0.05, 0.1) if quick else (0.01, 0.02, 0.03, 0.05, 0.07, 0.1, 0.2)
    warned: list = []
    hook = hasattr(mujoco, "set_mju_user_warning")
    if hook:                                          # unstable grid points: count, do not print
        previous = mujoco.get_mju_user_warning()
        mujoco.set_mju_user_warning(warned.append)
    try:
        grid = []
        for dt in dts:
            for damp in damps:
                model = mujoco.MjModel.from_xml_string(mujoco_xml(c, x0, dt, damp))
                k, _ = mujoco_steps_to(mujoco, model, x0, exact, tol, cap=20000)
                grid.append({"timestep_s": dt, "damping_Ns_per_m": damp, "steps_to_tol": k,
                             "sim_time_s": (k * dt if k else None)})
    finally:
        if hook:
            mujoco.set_mju_user_warning(previous)
    ok = [g for g in grid if g["steps_to_tol"]]
    if not ok:
        return {"error": "MuJoCo did not reach the tolerance on the grid", "grid": grid}
    best = min(ok, key=lambda g: g["steps_to_tol"])
    k = best["steps_to_tol"]
    xml = mujoco_xml(c, x0, best["timestep_s"], best["damping_Ns_per_m"])
    t0 = time.perf_counter()
    model = mujoco.MjModel.from_xml_string(xml)
    compile_s = time.perf_counter() - t0
    d = mujoco.MjData(model)

    def mj_run():
        mujoco.mj_resetData(model, d)
        mujoco.mj_step(model, d, k)

    ours_run = ours_elastic_runner(c, x0, [1e3])
    with counting(ours_run.model) as cnt:
        st = ours_run()
    # interleaved, so that both see the same machine load
    t_ours, t_mj = [], []
    for _ in range(repeats):
        t_ours.append(_timed(ours_run))
        t_mj.append(_timed(mj_run))
    err_mj = _err(x0 + d.qpos.reshape(-1, 2), exact)
    mujoco.mj_resetData(model, d)
    t0 = time.perf_counter()
    for _ in range(k):                       # one Python call per step, for reference
        mujoco.mj_step(model, d)
    loop_s = time.perf_counter() - t0
    med = lambda t, i: statistics.median(x[i] for x in t)  # noqa: E731
    ours = {"schedule_s": [1e3], "dynamic": False, "force_tol_N": 1e-9,
            "error_m": _err(st.x, exact),
            "wall_s": med(t_ours, 0), "cpu_s": med(t_ours, 1),
            "newton_iterations": cnt["newton"], "evaluations": cnt["evaluate"]}
    alternatives = [ours_elastic(c, exact, x0, s_, repeats=repeats // 2 + 1)
                    for s_ in ([1e3, 1e3], [0.1, 1e3], [0.01, 0.1, 1e3])]
    mj_wall, mj_cpu = med(t_mj, 0), med(t_mj, 1)
    return {
        "problem": {"n": c.n_masses, "span_m": 0.10, "drop_m": -0.08, "L0_m": 0.15,
                    "mu_kg_per_m": 0.3125,
                    "EA_N": 9.5, "tol_m": tol, "start": "straight line at rest (links slack)"},
        "ours": ours, "ours_alternatives": alternatives,
        "mujoco": {"representation": "per mass: body with slide joints x and z, point mass; per "
                                     "link: "
                                     "spatial tendon site-to-site, stiffness k_i, springlength '0 "
                                     "L_i' "
                                     "(tension-only linear spring); joint damping, implicitfast; "
                                     "contact and constraints disabled",
                   "timestep_s": best["timestep_s"], "damping_Ns_per_m": best["damping_Ns_per_m"],
                   "steps": k, "sim_time_s": k * best["timestep_s"], "error_m": err_mj,
                   "wall_s": mj_wall, "cpu_s": mj_cpu, "us_per_step": 1e6 * mj_cpu / k,
                   "python_loop_wall_s": loop_s, "compile_s": compile_s, "grid": grid,
                   "grid_warnings": len(warned)},
        "repeats": repeats,
        "mujoco_ratio": mj_wall / ours["wall_s"],
        "mujoco_ratio_cpu": mj_cpu / ours["cpu_s"],
    }


# ---------------------------------------------------------------- effects, cold start
def effects_table(repeats: int = 3) -> dict:
    """Cycle cost of the default cell (N = 63) with each effect alone at the top of its
    realistic range (rheo_shaping.sheet.effects), against the nominal cycle timed beside it."""
    from rheo_shaping.sheet.effects import EFFECTS
    p0, plan = cycle(CellParams().sheet.n_masses)
    rows = []
    for name, e in EFFECTS.items():
        p = e.apply(p0, [hi for _, hi in e.realistic])
        settle_wall, _ = time_settle(p, plan)
        time_cycle(p, plan)                                  # settle cached
        nominal, on = [], []
        for _ in range(repeats):                             # interleaved: same machine load
            nominal.append(time_cycle(p0, plan)[0])
            w, _, _, r = time_cycle(p, plan)
            on.append(w)
        with counting() as cnt:
            run_scenario(p, plan)
        steps = int(r.t.size - 1)
        rows.append({"effect": name, "values": [hi for _, hi in e.realistic],
                     "cycle_s": statistics.median(on),
                     "nominal_cycle_s": statistics.median(nominal),
                     "ratio": statistics.median(on) / statistics.median(nominal),
                     "settle_s": settle_wall, "steps": steps,
                     "newton_per_step": cnt["newton"] / steps,
                     "retried_steps": cnt["substeps"] - steps,
                     "F_max_N": r.F_max})
    return {"n": p0.sheet.n_masses, "repeats": repeats, "rows": rows,
            "max_ratio": max(r["ratio"] for r in rows)}


def cold_start(repeats: int = 3) -> dict:
    """Wall time [s] of ``rheo-shaping simulate --json`` as a user starts it (a fresh
    process), first with an empty compile cache, then with the cache it filled."""
    import shutil
    import subprocess
    import tempfile
    exe = Path(sys.executable).parent / "rheo-shaping"
    cmd = [str(exe)] if exe.exists() else [sys.executable, "-m", "rheo_shaping.cli"]
    cmd += ["simulate", "--json"]
    tmp = tempfile.mkdtemp(prefix="rheo-bench-cache-")
    env = dict(os.environ, NUMBA_CACHE_DIR=tmp)

    def timed() -> float:
        t0 = time.perf_counter()
        subprocess.run(cmd, env=env, check=True, capture_output=True, timeout=900)
        return time.perf_counter() - t0

    try:
        first = timed()
        warm = [timed() for _ in range(repeats)]
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return {"command": " ".join(cmd[-3:] if exe.exists() else cmd), "empty_cache_s": first,
            "cached_s": statistics.median(warm), "cached_runs_s": warm}


# ------------------------------------------------------------------------- main
def run(args) -> dict:
    out: dict = {"machine": machine_info(), "load_average_start": os.getloadavg(),
                 "cell_fingerprint": cell_fingerprint()}
    p0 = CellParams()
    out["cell"] = {"movement": 4, "process_time_s": p0.movement.process_time, "dt_s": p0.solver.dt,
                   "dt_still_s": p0.solver.dt_still, "max_tool_step_m": p0.solver.max_tool_step,
                   "settle_time_s": p0.solver.settle_time, "dt_settle_s": p0.solver.dt_settle,
                   "force_tol_N": p0.solver.force_tol}
    pin = one_core if args.pin else contextlib.nullcontext
    # 1. single-process, single-thread real-time factor at N = 25
    with pin() as cpu:
        p, plan = cycle(25)
        settles, runs = [], []
        for _ in range(args.repeats):
            settles.append(time_settle(p, plan))
            runs.append(time_cycle(p, plan))
    r = runs[-1][3]
    T = p.movement.process_time
    wall = statistics.median(x[0] for x in runs)
    cpu_s = statistics.median(x[2] for x in runs)
    settle = statistics.median(x[0] for x in settles)
    out.update({
        "rtf_n25": T / wall, "wall_s_n25": wall, "wall_s_n25_runs": [x[0] for x in runs],
        "rtf_n25_best": T / min(x[0] for x in runs), "rtf_n25_cpu": T / cpu_s, "cpu_s_n25": cpu_s,
        "rtf_n25_stepping_loop": T / statistics.median(x[1] for x in runs),
        "settle_wall_s_n25": settle, "settle_cpu_s_n25": statistics.median(x[1] for x in settles),
        "settle_sim_s": p.solver.settle_time,
        "settle_steps": int(math.ceil(p.solver.settle_time / p.solver.dt_settle - 1e-9)),
        "rtf_n25_with_settle": T / (wall + settle),
        "steps_n25": int(r.t.size - 1), "F_max_n25_N": r.F_max, "delta_n25_m": r.delta,
        "pinned_cpu": cpu, "rtf_repeats": args.repeats,
    })
    # 2. profile (main process, single core)
    with pin():
        out["profile"] = profile_cycle(25)
        out["profile"]["micro_us"] = micro(25, number=300 if args.quick else 2000)
    # 3. scaling, one fresh process per size
    jobs = []
    biggest = max(args.sizes)
    for n in args.sizes:
        t_end = args.t_end if (args.t_end and n >= args.shorten_from) else None
        trace = n == 25 or (n == biggest and args.trace_largest)
        jobs.append((n, args.repeats if n <= 100 else (2 if n <= 200 else 1), t_end, trace))
    results = {}
    ctx = multiprocessing.get_context("spawn")
    bar = _tqdm(total=len(jobs), desc="scaling", disable=args.no_progress)
    with ProcessPoolExecutor(max_workers=args.jobs, mp_context=ctx, max_tasks_per_child=1) as ex:
        futs = {ex.submit(size_job, *job): job[0] for job in sorted(jobs, key=lambda j: -j[0])}
        for fu in as_completed(futs):
            results[futs[fu]] = fu.result()
            bar.update(1)
    bar.close()
    out["scaling"] = [results[n] for n in sorted(results)]
    out["scaling_note"] = (f"{args.jobs} worker processes on {os.cpu_count()} cores, a fresh "
                           "process per size; "
                           f"medians of {args.repeats} runs for N <= 100, 2 for N <= 200, 1 above")
    out["peak_memory_mb"] = {
        f"n{s['n']}": {"tracemalloc_peak": s["tracemalloc_peak_mb"],
                       "peak_rss_during_cycles": s["peak_rss_during_cycles_mb"],
                       "rss_before_cycles": s["rss_before_cycles_mb"],
                       "ru_maxrss": s["ru_maxrss_mb"]}
        for s in out["scaling"] if s["n"] in (25, biggest)}
    stale = sorted({s["cell_fingerprint"] for s in out["scaling"]} - {out["cell_fingerprint"]})
    if stale:
        out["warning"] = ("the default cell changed during the run (params.py edited): main "
                          "process "
                          f"{out['cell_fingerprint']}, workers {stale}")
    # 4. each effect alone, and the cold start of the CLI
    if not args.no_effects:
        with pin():
            out["effects"] = effects_table(repeats=2 if args.quick else 3)
    if not args.no_cold_start:
        with pin():
            out["cold_start"] = cold_start(repeats=2 if args.quick else 3)
    # 5. MuJoCo on the shared elastic problem (single core)
    if not args.no_mujoco:
        with pin():
            mj = mujoco_compare(quick=args.quick)
        out["mujoco"] = mj
        out["mujoco_ratio"] = mj.get("mujoco_ratio")
    out["load_average_end"] = os.getloadavg()
    return out


def _tqdm(**kw):
    try:
        from tqdm import tqdm
        return tqdm(file=sys.stderr, **kw)
    except ImportError:                                # pragma: no cover
        class _Null:
            def update(self, *_):
                pass

            def close(self):
                pass
        return _Null()


def print_report(o: dict) -> None:
    m = o["machine"]
    print(f"machine: {m['platform']} | {m['cpu']} | {m['cpus']} CPUs | python {m['python']} | "
          f"numpy {m['numpy']} | scipy {m['scipy']} | mujoco {m['mujoco']}")
    print(
        f"default cell fingerprint {o['cell_fingerprint']} (sha1 of CellParams() as read at "
        "start)")
    la, lb = o["load_average_start"], o["load_average_end"]
    print(f"load average (1, 5, 15 min) at start {la[0]:.2f} {la[1]:.2f} {la[2]:.2f}, at end "
          f"{lb[0]:.2f} {lb[1]:.2f} {lb[2]:.2f} (other jobs share the machine: wall times include "
          "them)")
    print(f"\nN = 25, default cell, movement 4, {o['cell']['process_time_s']:g} s cycle, one "
          "process, one thread"
          f"{', pinned to CPU %s' % o['pinned_cpu'] if o['pinned_cpu'] is not None else ''} "
          f"(median of {o['rtf_repeats']}):")
    print(f"  cycle wall        {o['wall_s_n25']:.3f} s  -> rtf_n25 = {o['rtf_n25']:.0f}x real "
          "time "
          f"(best run {o['rtf_n25_best']:.0f}x, CPU time {o['rtf_n25_cpu']:.0f}x, stepping loop "
          "alone "
          f"{o['rtf_n25_stepping_loop']:.0f}x; {o['steps_n25']} steps)")
    print(f"  settle (cold)     {o['settle_wall_s_n25']:.3f} s wall, {o['settle_cpu_s_n25']:.3f} "
          "s CPU for "
          f"{o['settle_sim_s']:g} s of sag ({o['settle_steps']} inertial steps); cycle incl. "
          "settle "
          f"{o['rtf_n25_with_settle']:.0f}x")
    print(f"  F_max {o['F_max_n25_N']:.4f} N, Delta {1e3 * o['delta_n25_m']:.3f} mm")
    print(f"\nscaling ({o['scaling_note']}):")
    print(f"{'N':>5} {'sim s':>5} {'steps':>5} {'wall s':>7} {'wall/sim':>8} {'cpu/sim':>8} "
          f"{'rtf':>6} "
          f"{'settle s':>8} {'newton/st':>9} {'evals/st':>8} {'solves/st':>9} {'retry':>5} "
          f"{'peak RSS MB':>11}")
    for s in o["scaling"]:
        rss = s["peak_rss_during_cycles_mb"]
        print(f"{s['n']:>5} {s['sim_s']:>5g} {s['steps']:>5} {s['wall_s']:7.3f} "
              f"{s['wall_s_per_sim_s']:8.5f} "
              f"{s['cpu_s_per_sim_s']:8.5f} {s['rtf']:6.1f} {s['settle_wall_s']:8.3f} "
              f"{s['newton_iterations_mean']:9.2f} {s['evaluations_per_step']:8.2f} "
              f"{s['banded_solves_per_step']:9.2f} {s['retried_steps']:>5} "
              f"{(f'{rss:11.1f}' if rss is not None else f'{chr(45):>11}')}")
    pr = o["profile"]
    print(f"\nprofile of the N = 25 cycle (cProfile, {pr['profiled_wall_s']:.3f} s profiled, "
          f"{pr['steps']} steps);"
          " calls per step: " + ", ".join(f"{k} {v:.2f}" for k, v in pr["calls_per_step"].items()))
    print(f"  {'own s':>7} {'own %':>6} {'cum s':>7} {'cum %':>6} {'calls':>6}  function (by own "
          "time)")
    for r in pr["by_own_time"]:
        print(f"  {r['own_s']:7.4f} {r['own_pct']:6.1f} {r['cum_s']:7.4f} {r['cum_pct']:6.1f} "
              f"{r['calls']:>6}  "
              f"{r['function']}")
    print(f"  {'cum s':>7} {'cum %':>6} {'calls':>6}  function (by cumulative time)")
    for r in pr["by_cumulative_time"]:
        print(f"  {r['cum_s']:7.4f} {r['cum_pct']:6.1f} {r['calls']:>6}  {r['function']}")
    print("  own time: " + ", ".join(f"{k} {v}%" for k, v in pr["own_time_pct"].items()))
    mu = pr.get("micro_us", {})
    if "error" in mu:
        print(f"  per-call costs: unavailable ({mu['error']})")
    else:
        print("  per-call CPU costs without the profiler [us] at t = %.4g s (contacts %s):"
              % (mu["state_t_s"], mu["contacts"]))
        print("   " + ", ".join(f"{k[:-3]} {v}" for k, v in mu.items() if k.endswith("_us")))
    if o.get("warning"):
        print(f"\nWARNING: {o['warning']}")
    print("\npeak memory [MB]: " + "; ".join(
        f"{k}: tracemalloc peak "
        f"{_maybe_round(v['tracemalloc_peak'], 2)}, peak RSS during the cycles "
        f"{_maybe_round(v['peak_rss_during_cycles'], 1)} "
        f"(RSS before {v['rss_before_cycles']:.1f}, process ru_maxrss {v['ru_maxrss']:.1f})"
        for k, v in o["peak_memory_mb"].items()))
    ef = o.get("effects")
    if ef:
        print(f"\neach effect alone at the top of its realistic range, default cell N = {ef['n']} "
              f"(cycle with the settle cached; medians of {ef['repeats']}, interleaved with the "
              "nominal):")
        print(f"  {'effect':<15} {'values':<22} {'cycle s':>8} {'nominal s':>9} {'ratio':>6} "
              f"{'settle s':>8} {'newton/st':>9} {'F_max N':>8}")
        for r in ef["rows"]:
            vals = ", ".join(f"{v:g}" for v in r["values"])
            print(f"  {r['effect']:<15} {vals:<22} {r['cycle_s']:8.4f} "
                  f"{r['nominal_cycle_s']:9.4f} "
                  f"{r['ratio']:6.2f} {r['settle_s']:8.4f} {r['newton_per_step']:9.2f} "
                  f"{r['F_max_N']:8.4f}")
        print(f"  largest ratio {ef['max_ratio']:.2f}")
    cs = o.get("cold_start")
    if cs:
        print(f"\ncold start, `{cs['command']}` in a fresh process: empty compile cache "
              f"{cs['empty_cache_s']:.2f} s, cache filled {cs['cached_s']:.2f} s (runs "
              + ", ".join(f"{x:.2f}" for x in cs["cached_runs_s"]) + ")")
    mj = o.get("mujoco")
    if mj:
        if "error" in mj:
            print(f"\nMuJoCo: {mj['error']}")
            return
        pb, ours, mm = mj["problem"], mj["ours"], mj["mujoco"]
        print(f"\nshared elastic problem: N = {pb['n']}, span {pb['span_m']} m, drop "
              f"{pb['drop_m']} m, "
              f"L0 {pb['L0_m']} m, {pb['mu_kg_per_m']} kg/m, EA {pb['EA_N']} N, until max node "
              "error <= "
              f"{pb['tol_m']:g} m vs the exact discrete equilibrium; {pb['start']} (medians of "
              f"{mj['repeats']}, "
              "ours and MuJoCo interleaved)")
        print(f"  ours:   quasi-static step(s) {ours['schedule_s']} s: "
              f"{ours['newton_iterations']} Newton "
              f"iterations, {ours['evaluations']} energy evaluations, error {ours['error_m']:.1e} "
              "m, "
              f"wall {1e3 * ours['wall_s']:.2f} ms (CPU {1e3 * ours['cpu_s']:.2f} ms)")
        for a in mj["ours_alternatives"]:
            print(f"          (alternative {a['schedule_s']} s: {a['newton_iterations']} "
                  "iterations, "
                  f"{a['evaluations']} evaluations, error {a['error_m']:.1e} m, "
                  f"{1e3 * a['wall_s']:.2f} ms)")
        print(f"  MuJoCo: dt {mm['timestep_s']:g} s, joint damping {mm['damping_Ns_per_m']:g} N "
              "s/m (best of a "
              f"{len(mm['grid'])}-point grid): {mm['steps']} steps = {mm['sim_time_s']:.3f} s "
              "simulated, "
              f"error {mm['error_m']:.1e} m, wall {1e3 * mm['wall_s']:.2f} ms (CPU "
              f"{1e3 * mm['cpu_s']:.2f} ms, "
              f"{mm['us_per_step']:.1f} us/step; one Python call per step "
              f"{1e3 * mm['python_loop_wall_s']:.2f} ms;"
              f" compile {1e3 * mm['compile_s']:.1f} ms)")
        print(
            f"  mujoco_ratio = MuJoCo wall / ours = {mj['mujoco_ratio']:.2f} (CPU time "
            f"{mj['mujoco_ratio_cpu']:.2f})")
        fails = [g for g in mm["grid"] if not g["steps_to_tol"]]
        if fails:
            print("  grid points that diverged or did not reach the tolerance in 20000 steps: " +
                  ", ".join(f"(dt {g['timestep_s']:g}, c "
                            f"{g['damping_Ns_per_m']:g})" for g in fails))


def _maybe_round(x, digits):
    """``round(x, digits)``, None as it is."""
    return x if x is None else round(x, digits)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter,
                                 epilog=__doc__.split("\n\n", 1)[1])
    ap.add_argument("--json", action="store_true",
                    help="print one JSON object instead of the tables")
    ap.add_argument("--quick", action="store_true",
                    help="fewer repeats, sizes up to 200, small MuJoCo grid")
    ap.add_argument("--repeats", type=int, default=None,
                    help="timed repeats at N <= 100 (default 5, quick 3)")
    ap.add_argument("--sizes", type=int, nargs="+", default=None,
                    help="N of the scaling table (default 25 50 63 100 200 400 1000)")
    ap.add_argument("--jobs", type=int, default=min(2, os.cpu_count() or 1),
                    help="processes for the scaling sweep")
    ap.add_argument("--t-end", type=float, default=None,
                    help="shorten the simulated window [s] for N >= --shorten-from (default: "
                         "whole 120 s)")
    ap.add_argument("--shorten-from", type=int, default=200,
                    help="smallest N whose window --t-end shortens")
    ap.add_argument("--no-pin", dest="pin", action="store_false",
                    help="do not pin the single-core measurements to one CPU")
    ap.add_argument("--trace-largest", action="store_true",
                    help="also run the largest N under tracemalloc (doubles its cost)")
    ap.add_argument("--no-mujoco", action="store_true", help="skip the MuJoCo comparison")
    ap.add_argument("--no-effects", action="store_true", help="skip the effects cost table")
    ap.add_argument("--no-cold-start", action="store_true", help="skip the CLI cold-start timing")
    ap.add_argument("--no-progress", action="store_true", help="no progress bar")
    args = ap.parse_args(argv)
    if args.repeats is None:
        args.repeats = 3 if args.quick else 5
    if args.sizes is None:
        args.sizes = [n for n in SIZES if not (args.quick and n > 200)]
    out = run(args)
    if args.json:
        print(json.dumps(out, default=float))
    else:
        print_report(out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
