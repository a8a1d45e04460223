#!/usr/bin/env python3
"""Do a benchmark's verdicts hold with each threshold moved by +-20 %?  (issue 46, point 3)

Reads ``diagnose-benchmark --save`` files (their ``case_results``) and, per case, judges
again from what the case stored (the checked single effects' J, holdout J and values, the
baseline's J, the floor's 95 % quantile):

* the naming rule (:mod:`rheo_shaping.diagnosis.naming`) with each of its thresholds (most,
  ratio, prior) times 0.8 and 1.2: the lead and whether it is named;
* the gap test's bound (the floor's 95 % quantile times 0.8 and 1.2): is the baseline's
  excess J - 1 within it (``none``), read as J - 1 <= q95 (the conformal p > 0.05).

A case whose stored verdict the rule at its own thresholds does not give again (a pair,
the measurement chain) is counted apart, not judged.  Prints the flips per threshold and
writes them with ``--json FILE``.

    python benchmarks/naming_thresholds.py FILE.json [FILE.json ...] [--json OUT]
"""
from __future__ import annotations

import argparse
import json
import math
from types import SimpleNamespace

from rheo_shaping.diagnosis.naming import RULE, THRESHOLDS, judge, lead_key, moved
from rheo_shaping_validation.benchmark.score import row_level

#: The floor file of rows stored without their floor level (``--floor``).
FLOOR: list[str | None] = [None]

FACTORS = (0.8, 1.2)


def singles(row: dict) -> list:
    out = []
    for c in row.get("candidates") or []:
        if "+" in c["name"] or not c.get("checked") or c["J"] is None:
            continue
        J = float(c["J"]) if c["J"] is not None else math.inf
        Jh = float(c["J_holdout"]) if c.get("J_holdout") is not None else math.nan
        out.append(SimpleNamespace(names=(c["name"],), values={c["name"]: tuple(
            c["values"].get(c["name"], ()))}, J=J, J_holdout=Jh, checked=True))
    return out


def name_of(row: dict, rule) -> str:
    """The naming rule's verdict on ``row``'s stored candidates: an effect or unexplained."""
    effects = singles(row)
    if not effects:
        return "unexplained"
    Jb, Jbh = float(row["J_baseline"]), float(row["J_baseline_holdout"] or math.nan)
    lead = sorted(effects, key=lead_key(Jb, Jbh, rule))[0]
    r = judge(lead, effects, Jb, Jbh, math.isfinite(Jbh), row_level(row, FLOOR[0]), rule)
    return lead.names[0] if r.named else "unexplained"


def check_row(row: dict, rejudge: bool = False) -> dict:
    """The flips of ``row``'s verdict; ``rejudge``: of the verdict the rule as it is now gives
    on the row's stored candidates (a single effect or ``unexplained`` where the stored one is
    either; the gap test's ``none`` as stored), so that rows of an older rule are judged by
    this one."""
    if rejudge and row["verdict"] not in ("none", "measurement chain") \
            and "+" not in row["verdict"] and row.get("floor_q95") is not None:
        row = dict(row, verdict=name_of(row, RULE))
    out: dict = {"index": row["index"], "kind": row["kind"], "verdict": row["verdict"]}
    q = row.get("floor_q95")
    if q is None:
        out["judged"] = False
        return out
    flips = []
    excess = float(row["J_baseline"]) - 1.0
    if row["verdict"] == "none":
        for f in FACTORS:
            if excess > f * q:
                flips.append(f"floor q95 x{f}")
    elif row["verdict"] != "measurement chain" and "+" not in row["verdict"]:
        if name_of(row, RULE) != row["verdict"]:
            out["judged"] = False
            return out
        for t in THRESHOLDS:
            for f in FACTORS:
                if name_of(row, moved(RULE, t, f)) != row["verdict"]:
                    flips.append(f"{t} x{f}")
        for f in FACTORS:
            if excess <= f * q and row["verdict"] != "none":
                flips.append(f"floor q95 x{f}")
    else:
        out["judged"] = False
        return out
    out.update(judged=True, flips=flips)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("files", nargs="+")
    ap.add_argument("--json", default=None)
    ap.add_argument("--floor", default=None, help="the floor file of rows stored without "
                    "their floor level (their level from its median over its 95 %% quantile)")
    ap.add_argument("--rejudge", action="store_true", help="judge the verdicts the rule as "
                    "it is now gives on the stored candidates (rows of an older rule)")
    a = ap.parse_args()
    FLOOR[0] = a.floor
    rows = []
    for fn in a.files:
        with open(fn) as f:
            data = json.load(f)
        rows += [dict(check_row(r, a.rejudge), file=fn) for r in data["case_results"]]
    judged = [r for r in rows if r.get("judged")]
    flipped = [r for r in judged if r["flips"]]
    print(f"{len(rows)} cases, {len(judged)} judged again, {len(flipped)} flip under some "
          f"threshold +-20 %")
    for r in flipped:
        print(f"  {r['file']} case {r['index']} ({r['kind']}, {r['verdict']}): "
              f"{', '.join(r['flips'])}")
    if a.json:
        with open(a.json, "w") as f:
            json.dump({"cases": len(rows), "judged": len(judged), "flipped": len(flipped),
                       "rows": rows}, f, indent=1)


if __name__ == "__main__":
    main()
