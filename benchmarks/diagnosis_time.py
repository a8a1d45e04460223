"""What one diagnosis of three records costs: wall time and simulations, per kind of case.

Cases (records without the inverse crime, ``rheo_shaping_validation.benchmark.make_case``, two
fitted and one held out):

* ``free``: effect-free records (seed 11, case 5);
* ``offset``: a tool offset (seed 4, case 4), a plain gap case;
* ``kelvin``: a strong Kelvin creep (c1 = 785 N s/m, seed 1, case 34), which needs the
  relinearisation and the refined runs;
* ``kelvin-file``: records made from a written cell with c1 = 441 N s/m, diagnosed against it
  (the ``--write-scenario`` round trip: the model's own replay misfit is measured).

``--world dynamic --seed S --indices I,J,...``: instead, cases I, J, ... of the dynamic-world
benchmark of seed S (``diagnose-benchmark --world dynamic``: the same records, library, floor
``model-form`` and initial state ``auto``), e.g. to time a fresh seed's cases on a quiet machine.

``--n-masses`` and ``--process-time`` set the diagnosis's cell (default: the benchmark's, 31 and
70 s; the default cell is 63 and 120 s).  Prints one line per case and repetition, then the
median per case, with the machine's core count and load average; a dynamic-world case also
with the CPU seconds of this process and its pool's workers.  ``--stages``: each case's
wall time split by the diagnosis's stages (:data:`rheo_shaping.diagnosis.evaluate.STAGES`,
the time from a stage's start to the next one's).  ``--save FILE``: every case's verdict,
fitted effect values, J and J_holdout of the named fit, baseline J and simulations as JSON
(two such files, of two versions of the code, are compared by
``benchmarks/diagnosis_agree.py``).

    python benchmarks/diagnosis_time.py [--cases free,offset,kelvin,kelvin-file] [--repeat 1]
        [--jobs 2] [--n-masses 31] [--process-time 70]
    python benchmarks/diagnosis_time.py --world dynamic --seed 26003 --indices 0,1,3
        --n-masses 63 --process-time 120 [--stages] [--save FILE]
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import time
from dataclasses import replace

CASES = {"free": ("none", 5, 11), "offset": ("single", 4, 4), "kelvin": ("single", 34, 1)}


def records_of(name: str, base):
    """The three records of case ``name`` on the diagnosis cell ``base``."""
    from rheo_shaping_validation.benchmark import make_case
    from rheo_shaping.planning.movement import synthesize_record
    from rheo_shaping.sheet.effects import EFFECTS
    if name in CASES:
        return make_case(CASES[name][1], CASES[name][0], CASES[name][2], base)["records"]
    written = EFFECTS["kelvin_c1"].apply(base, (441.0,))
    out = []
    for m in (4, 2, 1):
        w = replace(written, movement=replace(written.movement, number=m))
        out.append(replace(synthesize_record(w, seed=500 + m, name=f"m{m}")[0], scenario=w))
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cases", default="free,offset,kelvin,kelvin-file")
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--n-masses", type=int, default=31)
    ap.add_argument("--process-time", type=float, default=70.0, help="record length [s]")
    ap.add_argument("--world", choices=("finer-chain", "dynamic"), default="finer-chain",
                    help="finer-chain: the --cases above; dynamic: --seed and --indices")
    ap.add_argument("--seed", type=int, default=None, help="dynamic-world benchmark seed")
    ap.add_argument("--indices", default="", help="dynamic-world case indices, e.g. 0,1,3")
    ap.add_argument("--stages", action="store_true", help="each case's time by stage")
    ap.add_argument("--save", default="", help="verdicts and fitted values as JSON")
    args = ap.parse_args(argv)
    if args.world == "dynamic":
        try:
            idx = [int(i) for i in args.indices.split(",") if i.strip()]
        except ValueError:
            ap.error(f"--indices: expected integers separated by commas, got {args.indices!r}")
        if args.seed is None or not idx or min(idx) < 0 or args.repeat < 1:
            ap.error("--world dynamic needs --seed S and --indices I,J,... (>= 0); --repeat >= 1")
        return dynamic_cases(args, idx)
    names = [c for c in args.cases.split(",") if c]
    bad = [c for c in names if c not in (*CASES, "kelvin-file")]
    if bad or args.repeat < 1:
        ap.error(f"--cases from {', '.join((*CASES, 'kelvin-file'))} (got {bad}); "
                 "--repeat >= 1")
    from rheo_shaping_validation.benchmark import base_cell
    from rheo_shaping.diagnosis.engine import diagnose
    from rheo_shaping.diagnosis.evaluate import default_executor
    base = base_cell(args.n_masses, args.process_time)
    print(f"{os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f} at the start; "
          f"N = {args.n_masses}, {args.process_time:g} s records, {args.jobs} workers")
    times: dict[str, list[float]] = {}
    with default_executor(args.jobs) as ex:
        # warm the workers
        diagnose(records_of("free", base)[:1], executor=ex, floor="numerics",
                 initial_state="settled")
        for name in names:
            try:
                rec = records_of(name, base)
            except RuntimeError as exc:     # the benchmark's draw has no valid case on this cell
                print(f"{name:12s} no records on this cell: {exc}", flush=True)
                continue
            for _ in range(args.repeat):
                t0 = time.perf_counter()
                d = diagnose(rec[:2], rec[2:], executor=ex, floor="numerics",
                             initial_state="settled")
                wall = time.perf_counter() - t0
                times.setdefault(name, []).append(wall)
                print(f"{name:12s} {d.verdict_name:18s} {wall:6.1f} s  {d.runs:4d} simulations  "
                      f"load {os.getloadavg()[0]:.1f}", flush=True)
    for name, ts in times.items():
        print(f"median {name:12s} {statistics.median(ts):6.1f} s over {len(ts)}")
    return 0


def dynamic_cases(args, indices: list[int]) -> int:
    """Time the dynamic-world benchmark's cases ``indices`` of ``args.seed`` as it diagnoses
    them (its library, floor and initial state), the records made before the clock starts."""
    from rheo_shaping_validation.benchmark import KINDS_PATTERN, base_cell, library_for, make_case
    from rheo_shaping.diagnosis.engine import diagnose
    from rheo_shaping.diagnosis.evaluate import default_executor
    base = base_cell(args.n_masses, args.process_time)
    print(f"{os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f} at the start; "
          f"dynamic world, seed {args.seed}; N = {args.n_masses}, {args.process_time:g} s "
          f"records, {args.jobs} workers")
    times, saved = [], []
    totals: dict[str, float] = {}
    with default_executor(args.jobs) as ex:
        for i in indices:
            kind = KINDS_PATTERN[i % len(KINDS_PATTERN)]
            case = make_case(i, kind, args.seed, base, world="dynamic")
            library = library_for(case)
            for _ in range(args.repeat):
                clock = StageClock()
                cpu0 = cpu_seconds(ex)
                t0 = time.perf_counter()
                d = diagnose(case["records"][:2], case["records"][2:], library=library,
                             executor=ex, floor="model-form", initial_state="auto",
                             progress=clock)
                wall = time.perf_counter() - t0
                cpu = cpu_seconds(ex) - cpu0
                times.append(wall)
                split = clock.split(t0 + wall)
                for k, v in split.items():
                    totals[k] = totals.get(k, 0.0) + v
                print(f"case {i:3d} {kind:14s} {d.verdict_name:22s} {wall:6.1f} s  {d.runs:4d} "
                      f"simulations  cpu {cpu:6.1f} s  load {os.getloadavg()[0]:.1f}",
                      flush=True)
                if args.stages:
                    print("         " + "; ".join(f"{k} {v:.1f} s ({n})" for (k, v), n in
                                                  zip(split.items(), clock.counts())),
                          flush=True)
                saved.append({"index": i, "kind": kind, "wall_s": wall, "cpu_s": cpu,
                              "load": os.getloadavg()[0], "stages_s": split, **outcome(d)})
    print(f"median {statistics.median(times):6.1f} s, max {max(times):6.1f} s over {len(times)}")
    if args.stages and totals:
        whole = sum(totals.values())
        print("by stage, all cases: " + "; ".join(f"{k} {v:.1f} s ({100 * v / whole:.0f} %)"
                                                  for k, v in totals.items()))
    if args.save:
        with open(args.save, "w") as f:
            json.dump({"seed": args.seed, "n_masses": args.n_masses,
                       "process_time_s": args.process_time, "jobs": args.jobs,
                       "cases": saved}, f, indent=1)
    return 0


def cpu_seconds(executor) -> float:
    """CPU seconds (user + system) spent so far by this process and the local pool
    ``executor``'s worker processes (read from /proc; this process alone elsewhere): a
    figure the machine's other work moves less than the wall time."""
    own = os.times()
    total = own.user + own.system
    tick = os.sysconf("SC_CLK_TCK") if hasattr(os, "sysconf") else 100
    for pid in list(getattr(executor, "_processes", None) or {}):
        try:
            with open(f"/proc/{pid}/stat") as f:
                fields = f.read().rsplit(")", 1)[1].split()
            total += (int(fields[11]) + int(fields[12])) / tick
        except (OSError, IndexError, ValueError):
            continue
    return total


class StageClock:
    """A progress display that notes when each stage of the diagnosis begins and how many
    simulations it runs (:meth:`rheo_shaping.diagnosis.evaluate.Runner.stage`)."""

    def __init__(self) -> None:
        self.marks: list[tuple[str, float]] = [("set-up", time.perf_counter())]
        self.runs: dict[str, int] = {}

    def stage(self, k: int, n: int, name: str, total) -> None:
        self.marks.append((name, time.perf_counter()))

    def __call__(self, n: int) -> None:
        name = self.marks[-1][0]
        self.runs[name] = self.runs.get(name, 0) + n

    def split(self, end: float) -> dict[str, float]:
        """Seconds from each stage's start to the next one's (the last: to ``end``); a
        stage entered twice adds up."""
        out: dict[str, float] = {}
        for (name, t), (_, t1) in zip(self.marks, self.marks[1:] + [("", end)]):
            out[name] = out.get(name, 0.0) + t1 - t
        return out

    def counts(self) -> list[int]:
        return [self.runs.get(k, 0) for k in self.split(time.perf_counter())]


def outcome(d) -> dict:
    """What the diagnosis ``d`` says, for comparing two versions of the code: the verdict,
    the named fit's values, J and J_holdout, the baseline's J and the simulations."""
    fit = d.verdict_fit
    return {"verdict": d.verdict_name, "J_base": d.J_base, "J_base_holdout": d.J_base_holdout,
            "p_gap": d.p_gap, "runs": d.runs,
            "values": ({n: list(v) for n, v in fit.values.items()} if fit else {}),
            "J": fit.J if fit else None, "J_holdout": fit.J_holdout if fit else None,
            "interval": ({n: [list(b) for b in iv] for n, iv in fit.interval.items()}
                         if fit else {}),
            "effects": [{"names": list(c.names), "J": c.J, "checked": c.checked,
                         "values": {n: list(v) for n, v in c.values.items()}}
                        for c in d.effects]}


if __name__ == "__main__":
    raise SystemExit(main())
