"""Calibrate the diagnosis's model-form floor on effect-free records of the dynamic world.

What the calibrated baseline leaves on records of a cell without any effect, when
the records come from a simulator of another form than the sheet model (the dynamic
world, ``rheo_shaping_validation.worlds``: inertia, soft contact, the sheet laid in a drawn shape
and released when the records begin, its own sensors), is the floor below which no gap
is worth an effect's name (issue 26, point 3).  Each case: a cell whose written
scenario and measurement chain are off within +-0.8 of their tolerances (the
benchmark's draws, ``diagnose-benchmark``), one laying, records of as many movements as
the largest grouping needs, drawn from 1-4 without repeats; the baseline is fitted with
the initial state read from the records (``initial_state="auto"``) on the first
``n_fit`` records and held out on the next ``n_holdout``, at each diagnosis chain size.
The world always runs 63 masses, so the
same records serve every chain size.

Stored per configuration (chain size, record length, fit and holdout counts): the
baseline's excess J - 1 on fit and holdout records, its systematic profile RMS [m] and
tool-force RMS [N], and the noise, in ``rheo_shaping/data/diagnosis_floor.json``
(``--out``), with how it was made.

    python benchmarks/diagnosis_floor.py --cases 24 --seed 97 --process-times 60,120 \\
        --n-masses 31,63 --groupings 1+1,2+1,3+1 [--jobs 2 | --executor dask://HOST:PORT]
        [--out FILE] [--json]

Each finished case is appended to ``FILE.partial.jsonl`` first; ``--assemble`` builds
the data file from that (an interrupted run keeps its cases).  ``--variations all`` draws
the world's form per case (issue 46, :mod:`rheo_shaping_validation.worlds.forms`), and
``--stratify`` spreads them over the cases instead (each variation off in half of them, on in
half with its values one to each equal part of its range: the soft mould's end included,
which 25 random draws missed), and
``--assemble --without V --out FILE_V`` (with ``FILE``'s partial file copied to
``FILE_V.partial.jsonl``) keeps only the cases with V off: the floor a held-out V is
judged against.
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from concurrent.futures import as_completed
from dataclasses import replace
from pathlib import Path

import numpy as np

DEFAULT_OUT = Path(__file__).resolve().parent.parent / "rheo_shaping" / "data" / \
    "diagnosis_floor.json"


def _with_n(rec, n: int):
    sc = rec.scenario
    return replace(rec, scenario=replace(sc, sheet=replace(sc.sheet, n_masses=n)))


def one_case(shared: dict, index: int) -> list[dict]:
    """Case ``index`` at record length ``shared['process_time']``: a row per chain size and
    grouping (module-level: it pickles to a worker)."""
    from rheo_shaping_validation.benchmark import base_cell, make_case
    from rheo_shaping.diagnosis.engine import diagnose
    T = shared["process_time"]
    t0 = time.monotonic()
    case = make_case(index, "none", shared["seed"], base_cell(31, T), world="dynamic",
                     n_records=max(nf + nh for nf, nh in shared["groupings"]),
                     variations=tuple(shared.get("variations", ())),
                     strata=int(shared.get("strata", 0)))
    t_world = time.monotonic() - t0
    rows = []
    for n in shared["n_masses"]:
        recs = [_with_n(r, n) for r in case["records"]]
        for nf, nh in shared["groupings"]:
            t1 = time.monotonic()
            diag = diagnose(recs[:nf], recs[nf:nf + nh], library=(), jobs=1,
                            initial_state="auto", floor="numerics")
            gb = diag.gap_baseline.as_json()
            rows.append({
                "index": index, "process_time_s": T, "n_masses": n, "n_fit": nf,
                "n_holdout": nh, "movements": case["movements"][:nf + nh], "lay": case["lay"],
                "J_fit": diag.J_base - 1.0, "J_holdout": diag.J_base_holdout - 1.0,
                "profile_sys_m": gb.get("fit", {}).get("profile_systematic_m"),
                "force_sys_N": gb.get("fit", {}).get("force_systematic_N"),
                "profile_sys_holdout_m": gb.get("holdout", {}).get("profile_systematic_m"),
                "force_sys_holdout_N": gb.get("holdout", {}).get("force_systematic_N"),
                "noise": diag.noise.as_json(), "initial": diag.initial_state, "form": case["form"],
                "diagnosis_s": time.monotonic() - t1, "world_s": t_world})
    return rows


def off(row: dict, variation: str) -> bool:
    """The case of ``row`` was drawn with ``variation`` off (rows of a run without
    variations have every one off)."""
    from rheo_shaping_validation.worlds.forms import FormParams
    form = row.get("form") or {}
    default = getattr(FormParams(), variation)
    return form.get(variation, default) == default


def assemble(rows: list[dict], how: dict, without: str | None = None) -> dict:
    """The data file: per configuration the sorted excesses and the physical remainders;
    ``without``: only the cases drawn with that form variation off (a leave-one-world-out
    floor, issue 46)."""
    groups: dict = {}
    if without:
        rows = [r for r in rows if off(r, without)]
        how = {**how, "without_variation": without}
    for r in rows:
        key = (r["n_masses"], r["process_time_s"], r["n_fit"], r["n_holdout"])
        groups.setdefault(key, []).append(r)
    configs = []
    for (n, T, nf, nh), rs in sorted(groups.items()):
        rs = sorted(rs, key=lambda r: r["index"])
        configs.append({
            "n_masses": n, "process_time_s": T, "n_fit": nf, "n_holdout": nh,
            "cases": len(rs),
            "fit": [r["J_fit"] for r in rs],
            "holdout": [r["J_holdout"] for r in rs if nh],
            "profile_sys_m": [r["profile_sys_m"] for r in rs],
            "force_sys_N": [r["force_sys_N"] for r in rs],
            "profile_noise_m": float(np.median([r["noise"]["profile_m"] for r in rs])),
            "force_noise_N": float(np.median([r["noise"]["force_N"] for r in rs])),
            "laid_share": float(np.mean([r["initial"]["mode"] == "laid" for r in rs]))})
    return {"how": how, "configs": configs}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--cases", type=int, default=24, help="effect-free cases per record length")
    ap.add_argument("--seed", type=int, default=97)
    ap.add_argument("--process-times", default="60,120", help="record lengths [s]")
    ap.add_argument("--n-masses", default="31,63", help="diagnosis chain sizes")
    ap.add_argument("--groupings", default="1+1,2+1,3+1", help="fit+holdout record counts")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--executor", default=None, help="local|local:N|serial|dask://HOST:PORT")
    ap.add_argument("--out", type=Path, default=DEFAULT_OUT)
    ap.add_argument("--assemble", action="store_true",
                    help="only build the data file from FILE.partial.jsonl")
    ap.add_argument("--json", action="store_true", help="print the data file")
    ap.add_argument("--variations", default="",
                    help="the dynamic world's form variations drawn per case (issue 46): 'all' "
                         "or names separated by commas (default none)")
    ap.add_argument("--stratify", action="store_true",
                    help="the variations stratified over the --cases cases (a Latin hypercube: "
                         "each off in half, on in half with its values spread over its whole "
                         "range, ends included) instead of drawn at random per case")
    ap.add_argument("--without", default=None, metavar="VARIATION",
                    help="build the data file from the cases with this variation off only (a "
                         "leave-one-world-out floor)")
    a = ap.parse_args(argv)
    from rheo_shaping.parallel import executor_from_spec
    partial = a.out.with_suffix(".partial.jsonl")
    times = [float(x) for x in a.process_times.split(",")]
    ns = [int(x) for x in a.n_masses.split(",")]
    groupings = [tuple(int(v) for v in g.split("+")) for g in a.groupings.split(",")]
    from rheo_shaping_validation.worlds.forms import Variation, check_variations
    variations = [v.value for v in check_variations(
        [v.value for v in Variation] if a.variations == "all"
        else [x for x in a.variations.split(",") if x])]
    if a.without:
        check_variations([a.without])
    try:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True,
                                text=True, cwd=Path(__file__).parent).stdout.strip()
    except OSError:
        commit = ""
    how = {"script": "benchmarks/diagnosis_floor.py", "args": sys.argv[1:] if argv is None
           else list(argv), "seed": a.seed, "cases_per_length": a.cases, "world": "dynamic",
           "commit": commit, "variations": variations,
           "strata": a.cases if a.stratify and variations else 0,
           "what": "baseline excess J - 1 (fit, holdout) on effect-free dynamic-world records, "
                   "initial state read from the records (auto), written scenario and chain "
                   "off within +-0.8 tolerance, a drawn laying, movements 1-4 in a drawn "
                   "order (as many as the largest grouping needs; the first n_fit fitted, "
                   "the next n_holdout held out); "
                   "case i of seed s is diagnose-benchmark's draw seed * 1000 + i"}
    if not a.assemble:
        done = set()
        if partial.exists():
            for line in partial.read_text().splitlines():
                r = json.loads(line)
                done.add((r["process_time_s"], r["index"]))
        todo = [(T, i) for T in times for i in range(a.cases) if (T, i) not in done]
        t0 = time.monotonic()
        with executor_from_spec(a.executor or f"local:{a.jobs}", a.jobs) as ex:
            futs = {ex.submit(one_case, {"seed": a.seed, "process_time": T, "n_masses": ns,
                                         "groupings": groupings, "variations": variations,
                                         "strata": a.cases if a.stratify else 0},
                              i): (T, i) for T, i in todo}
            for k, f in enumerate(as_completed(futs)):
                rows = f.result()
                with partial.open("a") as fh:
                    for r in rows:
                        fh.write(json.dumps(r, default=float) + "\n")
                T, i = futs[f]
                print(f"[{k + 1}/{len(todo)}] T {T:.0f} s case {i}: "
                      + ", ".join(f"N{r['n_masses']} {r['n_fit']}+{r['n_holdout']} "
                                  f"{r['J_fit']:.3f}/{r['J_holdout']:.3f}" for r in rows)
                      + f" ({time.monotonic() - t0:.0f} s)", file=sys.stderr, flush=True)
    rows = [json.loads(line) for line in partial.read_text().splitlines()]
    data = assemble(rows, how, a.without)
    a.out.write_text(json.dumps(data, indent=1, default=float) + "\n")
    if a.json:
        json.dump(data, sys.stdout, indent=1, default=float)
    else:
        for c in data["configs"]:
            f = np.sort(c["fit"])
            print(f"N {c['n_masses']} T {c['process_time_s']:.0f} s {c['n_fit']}+"
                  f"{c['n_holdout']}: {c['cases']} cases, J - 1 fit median {np.median(f):.3f}"
                  f" max {f[-1]:.3f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
