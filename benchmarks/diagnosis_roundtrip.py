"""``diagnose --write-scenario`` round trip: records made from the written file diagnose as `none`.

For each case (benchmark cases without the inverse crime, their own seed): diagnose two records
with a third held out, write the corrected cell (calibrated baseline + verdict's effect) as a
params file, make three new records from that file (``rheo-shaping record --params FILE``'s
path: the file's own cell, default measurement model, new noise seeds), diagnose them against the
file, and print both verdicts.  Usage: ``python benchmarks/diagnosis_roundtrip.py [N] [SEED]``.
"""
from __future__ import annotations

import sys
import tempfile
from dataclasses import replace
from pathlib import Path

from rheo_shaping.params.config import dump_cell, load_cell
from rheo_shaping_validation.benchmark import base_cell, make_case
from rheo_shaping.diagnosis.engine import diagnose
from rheo_shaping.planning.movement import synthesize_record

KINDS = ("single", "single", "none")


def main() -> None:
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 3
    seed = int(sys.argv[2]) if len(sys.argv) > 2 else 5
    ok = 0
    for i in range(n):
        case = make_case(2 * i + 2, KINDS[i % len(KINDS)], seed, base_cell())
        d = diagnose(case["records"][:2], case["records"][2:], jobs=2, floor="numerics",
                     initial_state="settled")
        with tempfile.TemporaryDirectory() as tmp:
            f = Path(tmp) / "corrected.yaml"
            f.write_text(dump_cell(d.corrected))
            cell = load_cell(f)
        recs = []
        for m in case["movements"]:
            cm = replace(cell, movement=replace(cell.movement, number=m))
            rec = synthesize_record(cm, seed=100 * seed + 10 * i + m, name=f"rt{i}-m{m}")[0]
            recs.append(replace(rec, scenario=cm))      # scenario.yaml = the written file
        d2 = diagnose(recs[:2], recs[2:], jobs=2, floor="numerics",
                      initial_state="settled")
        ok += d2.verdict == "none"
        print(f"case {i}: truth {case['truth'] or '-'}; verdict {d.verdict_name}; records "
              f"from the written file: {d2.verdict_name} (p_gap {d2.p_gap:.3g}, "
              f"J - 1 = {d2.J_base - 1:.4f})",
              flush=True)
    print(f"round trip `none`: {ok} of {n}")


if __name__ == "__main__":
    main()
