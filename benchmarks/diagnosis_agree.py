"""Do two versions of the diagnosis say the same on the same cases?

Reads two files of ``benchmarks/diagnosis_time.py --save`` (the same seed, cases and cell,
run on two versions of the code) and prints, case by case, both verdicts, both named fits'
values, J and J_holdout, and their relative differences; then how many verdicts agree and
the largest relative difference of a named value and of J.  Exit status 1 when a verdict
differs.

    python benchmarks/diagnosis_agree.py OLD.json NEW.json
"""
from __future__ import annotations

import json
import math
import sys


def rel(a: float | None, b: float | None) -> float:
    """|a - b| / max(|a|, |b|) (0 when both are 0 or both missing; inf when one is)."""
    if a is None and b is None:
        return 0.0
    if a is None or b is None or not (math.isfinite(a) and math.isfinite(b)):
        return 0.0 if a == b else math.inf
    scale = max(abs(a), abs(b))
    return 0.0 if scale == 0 else abs(a - b) / scale


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if len(argv) != 2:
        print(__doc__.split("\n\n")[-1].strip())
        return 2
    old, new = (json.load(open(p)) for p in argv)
    by_new = {c["index"]: c for c in new["cases"]}
    same, total, worst_v, worst_J = 0, 0, 0.0, 0.0
    for a in old["cases"]:
        b = by_new.get(a["index"])
        if b is None:
            print(f"case {a['index']:3d}: not in {argv[1]}")
            continue
        total += 1
        agree = a["verdict"] == b["verdict"]
        same += agree
        dv = max([rel(x, y) for n in set(a["values"]) | set(b["values"])
                  for x, y in zip(a["values"].get(n, [None]), b["values"].get(n, [None]))]
                 or [0.0])
        dJ = max(rel(a["J"], b["J"]), rel(a["J_base"], b["J_base"]))
        worst_v, worst_J = max(worst_v, dv), max(worst_J, dJ)
        print(f"case {a['index']:3d} {a['kind']:14s} {a['verdict']:>20s} | {b['verdict']:20s} "
              f"{'same' if agree else 'DIFFERENT'}")
        print(f"    values {a['values']} | {b['values']}  (rel. diff {dv:.2g})")
        print(f"    J_base {a['J_base']:.4f} | {b['J_base']:.4f}; J {a['J']} | {b['J']}; "
              f"J_holdout {a['J_holdout']} | {b['J_holdout']}; simulations {a['runs']} | "
              f"{b['runs']}; wall {a['wall_s']:.1f} | {b['wall_s']:.1f} s")
    print(f"verdicts the same: {same} of {total}; largest relative difference of a named "
          f"value {worst_v:.2g}, of J (named fit or baseline) {worst_J:.2g}")
    return 0 if same == total else 1


if __name__ == "__main__":
    raise SystemExit(main())
