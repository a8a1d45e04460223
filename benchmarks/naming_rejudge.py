#!/usr/bin/env python3
"""A benchmark's verdicts judged again by the naming rule as it is now, from what each case
stored (its checked candidates' J, holdout J and values, the pair checked, the measurement
chain's hypothesis, the baseline's J and the floor's 95 % quantile): what the rule alone
changes, without running anything (the search's own changes, which move the runs, are not in
it).  The verdict is taken as :func:`rheo_shaping.diagnosis.verdict.verdict_stage` takes it
against a model-form floor: the single effect of least effective remainder if the rule names
it (and the chain's hypothesis does not fit better), else the chain's hypothesis if the rule
names it, else the checked pair if the rule names it, else ``unexplained``; ``none`` where
the gap test found no gap.  The chain's timing check is not redone (the stored verdict's
side is kept where it was a load-cell lag refused).

    python benchmarks/naming_rejudge.py RUN.json.partial.jsonl [...] [--changed]
"""
from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
from types import SimpleNamespace

from rheo_shaping.diagnosis.naming import RULE, judge, lead_key
from rheo_shaping_validation.benchmark.score import row_level

#: The floor file of rows stored without their floor level (``--floor``).
FLOOR: list[str | None] = [None]


def _expl(c: dict | None, chain: bool = False):
    if c is None:
        return None
    J = float(c["J"]) if c.get("J") is not None else math.inf
    Jh = float(c["J_holdout"]) if c.get("J_holdout") is not None else math.nan
    return SimpleNamespace(names=() if chain else tuple(c["name"].split("+")),
                           values={} if chain else {k: tuple(v) for k, v in
                                                    c["values"].items()},
                           J=J, J_holdout=Jh, checked=True if chain else bool(c["checked"]))


def verdict(row: dict, rule=RULE) -> str:
    """The verdict the naming rule gives on ``row``'s stored candidates."""
    if row["p_gap"] > 0.05:
        return "none"
    Jb, Jbh = float(row["J_baseline"]), float(row["J_baseline_holdout"] or math.nan)
    has_h, q = math.isfinite(Jbh), row_level(row, FLOOR[0])
    cands = [_expl(c) for c in row["candidates"]]
    singles = [c for c in cands if len(c.names) == 1]
    pairs = [c for c in cands if len(c.names) == 2 and c.checked]
    chain = _expl(row["chain_candidate"], chain=True)

    def named(c) -> bool:
        return c.checked and math.isfinite(c.J) and judge(c, singles, Jb, Jbh, has_h, q,
                                                          rule).named
    timing_refused = (row["verdict"] != "measurement chain"
                      and "load_cell.lag" in row["chain_candidate"].get("outside", [])
                      and row.get("side") == "sheet")
    chain_ok = named(chain) and not timing_refused
    if singles:
        lead = sorted(singles, key=lead_key(Jb, Jbh, rule))[0]
        if named(lead) and not (chain_ok and chain.J < lead.J):
            return lead.names[0]
    if chain_ok:
        return "measurement chain"
    if pairs and named(pairs[0]):
        return "measurement chain" if chain_ok and chain.J < pairs[0].J else \
            "+".join(pairs[0].names)
    return "unexplained"


def figures(rows: list[dict], key: str) -> dict:
    """The acceptance figures of ``rows`` with their verdicts under ``key``."""
    out = {"single_beyond_floor_right": [0, 0], "none_rate": [0, 0], "none_library_name": [0, 0]}
    for r in rows:
        v, k = r[key], r["kind"]
        names = v.split("+") if v not in ("none", "unexplained", "measurement chain") else []
        if k == "single" and not (r["verdict"] == "none" and v == "none"):
            out["single_beyond_floor_right"][1] += 1
            out["single_beyond_floor_right"][0] += names == list(r["truth"])
        elif k == "none":
            out["none_rate"][1] += 1
            out["none_rate"][0] += v == "none"
            out["none_library_name"][1] += 1
            out["none_library_name"][0] += bool(names)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("files", nargs="+")
    ap.add_argument("--changed", action="store_true", help="list the cases whose verdict moves")
    ap.add_argument("--floor", default=None, help="the floor file of rows stored without "
                    "their floor level (their level from its median over its 95 %% quantile)")
    a = ap.parse_args()
    FLOOR[0] = a.floor
    for fn in a.files:
        rows = [json.loads(ln)["row"] for ln in Path(fn).read_text().splitlines() if ln.strip()]
        rows = [r for r in rows if "verdict" in r]
        for r in rows:
            r["rejudged"] = verdict(r)
        f = figures(rows, "verdict")
        g = figures(rows, "rejudged")
        print(f"{fn}: {len(rows)} cases")
        for k in f:
            print(f"  {k}: stored {f[k][0]}/{f[k][1]} -> now {g[k][0]}/{g[k][1]}")
        if a.changed:
            for r in rows:
                if r["rejudged"] != r["verdict"]:
                    print(f"    case {r['index']} ({r['kind']}, {dict(r['truth'])}): "
                          f"{r['verdict']} -> {r['rejudged']}")


if __name__ == "__main__":
    main()
