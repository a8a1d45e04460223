"""How far the named effects' intervals would have to be widened to hold the truth: a factor k
on each interval's half-widths about the fitted value, calibrated on one run's right names and
judged on another run's (docs/diagnosis.md, *The model-form part of an interval*).

    python benchmarks/interval_calibration.py CALIBRATION.jsonl [--judge OTHER.jsonl]

On the calibration run: per right name, the ratio of the value's error to the interval's
half-width on the error's side (the largest over the effect's parameters); k is that ratio's
0.95 quantile (numpy's linear interpolation).  On the judged run (or the calibration run
itself without --judge): the truth inside [v - k (v - lo), v + k (hi - v)] (clipped to the
library's bounds) and the median width relative to the value (or near zero to the library
range, as the benchmark's rows), beside the intervals as they are.
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from rheo_shaping.sheet.effects import EFFECTS
from rheo_shaping_validation.benchmark.score import relative_width


def named(path: str) -> list[tuple[str, np.ndarray, np.ndarray, np.ndarray]]:
    """(effect, truth, fitted, interval (k, 2)) of each right name with an interval."""
    out = []
    for ln in Path(path).read_text().splitlines():
        if not ln.strip():
            continue
        r = json.loads(ln)["row"]
        if r.get("in_interval") is None:
            continue
        n = list(r["truth"])[0]
        c = next(c for c in r["candidates"] if c["name"] == n)
        out.append((n, np.array(r["truth"][n], float), np.array(r["verdict_params"][n], float),
                    np.array(c["interval"][n], float)))
    return out


def ratio(t: np.ndarray, v: np.ndarray, iv: np.ndarray) -> float:
    half = np.where(t >= v, iv[:, 1] - v, v - iv[:, 0])
    return float(np.max(np.abs(t - v) / np.maximum(half, 1e-300)))


def widened(n: str, v: np.ndarray, iv: np.ndarray, k: float) -> np.ndarray:
    b = np.array(EFFECTS[n].bounds, float)
    return np.c_[np.maximum(v - k * (v - iv[:, 0]), b[:, 0]),
                 np.minimum(v + k * (iv[:, 1] - v), b[:, 1])]


def judge(rows, k: float) -> tuple[int, int, float]:
    hits, widths = 0, []
    for n, t, v, iv in rows:
        w = widened(n, v, iv, k)
        hits += bool(np.all((w[:, 0] <= t) & (t <= w[:, 1])))
        widths.append(relative_width(n, v, [tuple(x) for x in w]))
    return hits, len(rows), float(np.median(widths))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("calibration")
    ap.add_argument("--judge")
    a = ap.parse_args()
    cal = named(a.calibration)
    rs = [ratio(t, v, iv) for _, t, v, iv in cal]
    k = max(float(np.quantile(rs, 0.95)), 1.0)
    print(f"calibration: {len(cal)} right names; error / half-width: median "
          f"{np.median(rs):.2f}, 0.8 quantile {np.quantile(rs, 0.8):.2f}, k = 0.95 quantile "
          f"{k:.2f}")
    rows = named(a.judge) if a.judge else cal
    for label, kk in (("as they are", 1.0), (f"x {k:.2f}", k)):
        h, m, w = judge(rows, kk)
        print(f"{'judged' if a.judge else 'calibration'} run, intervals {label}: truth inside "
              f"{h} of {m} ({h / m:.2f}), median width {w:.3f}")


if __name__ == "__main__":
    main()
