"""The model-form part of an interval, estimated from the remainder (``intervals.py``): the
sandwich's closed forms, and its coverage on replicate linear problems with a correlated
discrepancy."""
from __future__ import annotations

import math

import numpy as np
import pytest

from rheo_shaping.diagnosis import intervals as iv


def _perp(A: np.ndarray, e: np.ndarray) -> np.ndarray:
    Q = np.linalg.qr(A, mode="reduced")[0]
    return e - Q @ (Q.T @ e)


def test_for_iid_noise_the_sandwich_is_the_classic_ols_variance():
    """Residual iid N(0, sigma^2): V = sigma^2 / |e|^2 within the estimator's own sampling
    spread, sqrt(2 sum v_b^2) / sum v_b of chi^2_1 block sums (v_b = sigma^2 |e_b|^2)."""
    rng = np.random.default_rng(11)
    n, sigma = 6000, 0.3
    e = rng.normal(size=n)
    r = sigma * rng.normal(size=n)
    block = np.arange(n) // 20                       # 300 blocks
    V, G = iv.sandwich(e, r, block)
    classic = sigma ** 2 / float(e @ e)
    vb = np.bincount(block, weights=sigma ** 2 * e ** 2)
    rel_sd = math.sqrt(2 * float(vb @ vb)) / float(vb.sum())
    assert G == 300
    assert abs(V[0, 0] / classic - 1) < 4 * rel_sd + 1.0 / G     # + the G / (G - 1) factor
    # the automatic blocks on an iid remainder stay short (one or two bins of a second)
    t = np.arange(n) * 0.02
    sp = iv.spread(e, r, np.zeros(n, int), t)
    assert sp.block_s <= 2.0
    assert abs(sp.cov[0, 0] / classic - 1) < 4 * math.sqrt(2 / sp.blocks) + 1.0 / sp.blocks


def test_a_constant_offset_within_each_block_gives_the_block_formula_exactly():
    rng = np.random.default_rng(3)
    n = 900
    e = rng.normal(size=n)
    block = np.arange(n) // 90                       # 10 blocks
    c = rng.normal(size=10)
    r = c[block]
    V, G = iv.sandwich(e, r, block)
    sums = np.bincount(block, weights=e)
    want = G / (G - 1) * float(np.sum((c * sums) ** 2)) / float(e @ e) ** 2
    assert G == 10
    assert V[0, 0] == pytest.approx(want, rel=1e-12)


def test_a_discrepancy_orthogonal_to_the_response_adds_nothing():
    """A discrepancy orthogonal to e_perp within every block adds exactly zero."""
    rng = np.random.default_rng(4)
    n = 1200
    A = rng.normal(size=(n, 5))
    e = _perp(A, rng.normal(size=n))
    block = np.arange(n) // 100
    noise = 0.1 * rng.normal(size=n)
    d = rng.normal(size=n)
    for b in range(12):                               # d's part along e, block by block, out
        m = block == b
        d[m] -= e[m] * float(e[m] @ d[m]) / float(e[m] @ e[m])
    V0, _ = iv.sandwich(e, noise, block)
    V1, _ = iv.sandwich(e, noise + d, block)
    assert V1[0, 0] == pytest.approx(V0[0, 0], rel=1e-10)


def test_andrews_length_grows_with_the_correlation():
    assert iv.andrews_length(0.0, 120) == 1.0
    assert iv.andrews_length(0.5, 120) < iv.andrews_length(0.9, 120) <= 120


def _replicate(rng, n_rec=2, T=120.0, rate=10.0, rho=0.995, k=4):
    """One linear problem: two records of ``T`` s at ``rate`` rows/s, baseline columns A, an
    effect column e (smooth in time), truth theta, an AR(1) discrepancy of correlation
    ``rho`` per row plus white noise; least squares on [A, e]."""
    n1 = int(T * rate)
    t = np.tile(np.arange(n1) / rate, n_rec)
    rec = np.repeat(np.arange(n_rec), n1)
    A = np.column_stack([np.ones_like(t)] + [np.sin((j + 1) * t / T * math.pi)
                                             for j in range(k - 1)])
    e = np.cos(3.0 * t / T * math.pi) + 0.5 * np.sin(7.0 * t / T * math.pi) * (rec + 1)
    d = np.empty_like(t)
    x = 0.0
    for i in range(t.size):
        x = rho * x + math.sqrt(1 - rho ** 2) * rng.normal()
        d[i] = x
    theta = 1.0
    y = theta * e + A @ rng.normal(size=k) + 0.3 * d + 0.1 * rng.normal(size=t.size)
    X = np.column_stack((A, e))
    coef = np.linalg.lstsq(X, y, rcond=None)[0]
    r = y - X @ coef
    sp = iv.spread(_perp(A, e), r, rec, t)
    return abs(coef[-1] - theta) <= sp.half[0], sp


def test_the_interval_covers_the_truth_under_a_correlated_discrepancy():
    """400 seeded replicates with an AR(1) discrepancy (correlation 0.995 per row at 10 rows/s,
    about 20 s): the truth inside the 95 % interval in at least 80 %, with a binomial margin
    of 3 standard deviations below the observed rate."""
    rng = np.random.default_rng(46)
    N = 400
    hits = [_replicate(rng)[0] for _ in range(N)]
    rate = sum(hits) / N
    assert rate - 3 * math.sqrt(rate * (1 - rate) / N) >= 0.80, rate


def test_the_family_factor_scales_each_side_about_the_value_within_the_bounds():
    out = iv.scaled("kelvin_c1", (500.0,), [(450.0, 520.0)], 2.0)
    assert out == [(pytest.approx(400.0), pytest.approx(540.0))]
    assert iv.scaled("friction_tool", (0.1,), [(0.0, 0.2)], 3.0)[0][0] == 0.0   # its bound
