#!/usr/bin/env python3
"""Every range's bounds run: each parameter at its minimum, its maximum and just inside an
open bound, through ``simulate``, ``record``, ``diagnose`` and the nodes (issue 27).

For every numeric leaf of the cell schema (``rheo_shaping.params``; arrays: every element
at the bound together) a params file is written from the default cell with that one value
changed, and run through ``rheo-shaping simulate`` (all), ``record`` (``--record-every``)
and ``diagnose`` of that record (``--diagnose-every``); every node setting
(``params.node_params``) at its bounds goes into its own node executable, which must either
refuse (exit 2, a message) or run and stop with exit 0 on SIGINT.  Pass: exit 0 or 2 and
no traceback; a run that takes longer than ``--timeout`` is reported as slow (a value
whose cost grows with it, e.g. 2000 masses), separately from failures.

    .venv/bin/python benchmarks/fuzz_bounds.py [--record-every 1] [--diagnose-every 4]
        [--nodes] [--timeout 300] [--only PREFIX] [--jobs 2] [--json OUT]
"""
from __future__ import annotations

import argparse
import concurrent.futures
import json
import math
import sys
import tempfile
import time
from pathlib import Path

import yaml

sys.path.insert(0, str(Path(__file__).resolve().parent))
from fuzz_inputs import BIN, run_cli, run_node  # noqa: E402

from rheo_shaping.params.config import dump_cell  # noqa: E402
from rheo_shaping.params.node_params import NODE_PARAMS  # noqa: E402
from rheo_shaping.params.cell import CellParams  # noqa: E402
from rheo_shaping.params.schema import iter_fields  # noqa: E402


def bound_values(fi) -> list[tuple[str, object]]:
    """(label, value) at the bounds of one leaf: min (or just inside an open min), max."""
    spec, kind = fi.spec, fi.kind
    if kind is bool or kind is str:
        return []
    out = []
    elem_int = kind is int or (kind is tuple and fi.default and isinstance(fi.default[0], int))
    if spec.lo is not None:
        lo = spec.lo
        if spec.lo_open:
            lo = (int(lo) + 1) if elem_int else math.nextafter(lo, math.inf) if lo == 0 else \
                lo * (1 + 1e-9) if lo > 0 else lo * (1 - 1e-9)
            out.append(("just above the open min", lo))
        else:
            out.append(("min", int(lo) if elem_int else float(lo)))
    if spec.hi is not None:
        out.append(("max", int(spec.hi) if elem_int else float(spec.hi)))
    if kind is tuple:
        n = len(fi.default)
        return [(label, [v] * n) for label, v in out] if n else []
    return out


def _set(tree: dict, dotted: str, value) -> None:
    node = tree["/**"]["ros__parameters"]
    *path, leaf = dotted.split(".")
    for k in path:
        node = node[k]
    node[leaf] = value


def cases() -> list[tuple[str, str, object]]:
    """(section, dotted name, value, label) of every bound of every parameter."""
    out = []
    for fi in iter_fields(CellParams):
        for label, v in bound_values(fi):
            out.append(("cell", fi.name, v, label))
    for node, cls in NODE_PARAMS.items():
        for fi in iter_fields(cls):
            for label, v in bound_values(fi):
                out.append((node, fi.name, v, label))
    return out


def write_case(work: Path, k: int, section: str, name: str, value) -> Path:
    tree = yaml.safe_load(dump_cell(CellParams()))
    if section == "cell":
        _set(tree, name, value)
    else:
        tree[f"/**/{section}"] = {"ros__parameters": {name: value}}
    path = work / f"case{k:04d}.yaml"
    path.write_text(yaml.safe_dump(tree, sort_keys=False))
    return path


def run_case(work: Path, k: int, case, args) -> dict:
    section, name, value, label = case
    params = write_case(work, k, section, name, value)
    res = {"section": section, "name": name, "value": value, "bound": label}
    t0 = time.monotonic()
    if section == "cell":
        res["simulate"] = run_cli([str(BIN / "rheo-shaping"), "simulate", "--params",
                                   str(params), "--json", "--quiet"], work, args.timeout)
        if k % args.record_every == 0:
            out = work / f"rec{k:04d}"
            res["record"] = run_cli([str(BIN / "rheo-shaping"), "record", "--params",
                                     str(params), "--out", str(out), "--seed", "1", "--quiet"],
                                    work, args.timeout)
            if res["record"] == "ok" and k % args.diagnose_every == 0:
                res["diagnose"] = run_cli([str(BIN / "rheo-shaping"), "diagnose", str(out),
                                           "--out", str(work / f"diag{k:04d}"), "--quiet"],
                                          work, args.timeout)
    elif args.nodes:
        res[section] = run_node(section, params, work, settle=5.0)
    res["wall_s"] = round(time.monotonic() - t0, 2)
    return res


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--record-every", type=int, default=1, metavar="K",
                    help="record every K-th cell case (default: all)")
    ap.add_argument("--diagnose-every", type=int, default=4, metavar="K",
                    help="diagnose the record of every K-th cell case (default 4)")
    ap.add_argument("--nodes", action="store_true", help="also each node setting's bounds")
    ap.add_argument("--timeout", type=float, default=300.0, help="s per command (default 300)")
    ap.add_argument("--only", default="", help="only parameters whose name starts with this")
    ap.add_argument("--jobs", type=int, default=2, help="cases at once (default 2)")
    ap.add_argument("--json", type=Path, default=None, help="write every result here")
    args = ap.parse_args(argv)
    todo = [c for c in cases() if c[1].startswith(args.only)
            and (c[0] == "cell" or args.nodes)]
    results, failures, slow = [], [], []
    t0 = time.monotonic()
    with tempfile.TemporaryDirectory(prefix="fuzz_bounds-") as tmp:
        work = Path(tmp)
        with concurrent.futures.ThreadPoolExecutor(args.jobs) as pool:
            futs = [pool.submit(run_case, work, k, c, args) for k, c in enumerate(todo)]
            for i, fut in enumerate(concurrent.futures.as_completed(futs), 1):
                r = fut.result()
                results.append(r)
                for cmd in ("simulate", "record", "diagnose", *NODE_PARAMS):
                    v = r.get(cmd)
                    if v is None or v in ("ok", "refused"):
                        continue
                    (slow if v.startswith("timeout") else failures).append((cmd, r, v))
                    print(f"\n{cmd} {r['name']} = {r['value']!r} ({r['bound']}): {v[:300]}",
                          flush=True)
                el = time.monotonic() - t0
                eta = el / i * (len(todo) - i)
                print(f"\r[{i}/{len(todo)}] {el:.0f} s, ETA {eta:.0f} s, failures "
                      f"{len(failures)}, slow {len(slow)}", end="", flush=True)
    print()
    tally: dict = {}
    for r in results:
        for cmd in ("simulate", "record", "diagnose", *NODE_PARAMS):
            v = r.get(cmd)
            if v is not None:
                slow_or_failed = "slow" if v.startswith("timeout") else "failure"
                key = v if v in ("ok", "refused") else slow_or_failed
                tally.setdefault(cmd, {}).setdefault(key, 0)
                tally[cmd][key] += 1
    print(json.dumps({"cases": len(todo), "tally": tally,
                      "wall_s": round(time.monotonic() - t0, 1)}, indent=1))
    for cmd, r, v in failures + slow:
        print(f"{cmd} {r['name']} = {r['value']!r} ({r['bound']}): {v[:400]}")
    if args.json:
        args.json.write_text(json.dumps(results, indent=1, default=str))
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
