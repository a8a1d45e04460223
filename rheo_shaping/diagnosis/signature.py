"""The signature of what the calibrated baseline leaves, and the kinds of cause it points to.

From the baseline's residuals on the fit records (chain errors removed):

* ``observables``: each observable's excess misfit (J_o - 1, 1 = the noise);
* ``where``: systematic RMS [m] in five equal bands of arc length from the
  cake-top bond; the band where it peaks;
* ``when``: systematic RMS per phase (:mod:`where`); ``before_contact`` is
  the approach phase's share (what no tool effect can cause);
* ``trend``: the per-frame systematic RMS in the last third of the process
  over the first third after the tool touches: ``growing`` (> 1.5),
  ``decaying`` (< 0.67) or ``constant``;
* ``proportional_to``: correlation of the per-frame systematic RMS with the
  model's mean tension, the tool's speed, the sheet's plastic strain and the
  tool's depth below home;
* ``force_lag_s``: the lag [s] of the measured tool force behind the model's
  (least squares of the force residual on the model force's rate; + the
  load cell lags) and ``force_gain``: the residual's share proportional to
  the model force.

:func:`rank_causes` scores the kinds of cause (``CAUSES``) from these
features (rules in docs/diagnosis.md, "Beyond the library"); a kind one of
whose library effects imitates at least ``SUBSTITUTE_SHARE`` of the gap on
its own (``partial``: the share of the baseline's excess it removes, though
not enough to be named) ranks first, by that share.
"""
from __future__ import annotations

import math

import numpy as np

from .where import PHASES, phases

CAUSES = ("contact friction", "rate-dependent rheology", "strain-dependent material",
          "bending stiffness", "mass or gravity load", "tool position calibration",
          "measurement chain")

#: The kind of cause each library effect belongs to (the benchmark scores the ranking by it).
KIND_OF_EFFECT = {"friction_mould": "contact friction", "friction_tool": "contact friction",
                  "kelvin_c1": "rate-dependent rheology", "power_law": "rate-dependent rheology",
                  "thinning": "strain-dependent material", "bending": "bending stiffness",
                  "mass_error": "mass or gravity load", "tool_offset": "tool position calibration"}


def _sys(r: np.ndarray, s: float) -> float:
    return math.sqrt(max(float(np.mean(r ** 2)) - s * s, 0.0)) if r.size else 0.0


def _corr(a: np.ndarray, b: np.ndarray) -> float:
    if a.size < 4 or np.std(a) == 0 or np.std(b) == 0:
        return 0.0
    return float(np.corrcoef(a, b)[0, 1])


#: A library effect that removes at least this share of the baseline's excess points to its kind.
SUBSTITUTE_SHARE = 0.3


def partial_shares(effects, J_base: float) -> dict:
    """Kind of cause -> the largest share of the baseline's excess one of its library effects
    removes on its own (fit records)."""
    out: dict = {}
    if not J_base > 1.0:
        return out
    for c in effects:
        if len(c.names) != 1 or not math.isfinite(c.J):
            continue
        kind = KIND_OF_EFFECT.get(c.names[0])
        if kind:
            out[kind] = max(out.get(kind, -math.inf), (J_base - c.J) / (J_base - 1.0))
    return out


def describe(data, res, runs, sp: float, sf: float, u_chain=None,
             partial: dict | None = None) -> dict:
    """The residual's signature on the fit records (see the module's docstring)."""
    prof = np.concatenate([r.profile for r in res])
    out: dict = {"observables": {"profile": float(np.mean(prof ** 2) / sp ** 2 - 1.0)}}
    forces = [r.force for r in res if r.force is not None]
    if forces:
        f = np.concatenate(forces)
        out["observables"]["tool force"] = float(np.mean(f ** 2) / sf ** 2 - 1.0)
    # where along the sheet
    rel_arc = np.concatenate([r.arc / max(float(np.sum(run.rest_length)), 1e-9)
                              for r, run in zip(res, runs)])
    bands = []
    for k in range(5):
        sel = (rel_arc >= k / 5) & (rel_arc < (k + 1) / 5 + (k == 4))
        bands.append(_sys(prof[sel], sp))
    out["where"] = {"bands_m": bands, "peak_band": int(np.argmax(bands)),
                    "peak_band_arc_fraction": [int(np.argmax(bands)) / 5,
                                               (int(np.argmax(bands)) + 1) / 5]}
    # when: phases and per-frame series
    ph_sys = {}
    frame_t, frame_sys, frame_feat = [], [], []
    ph_all = []
    for d, r, run in zip(data, res, runs):
        lab = phases(d, run)
        ph_all.append(lab[d.point_frame])
        t = d.record.profile_t
        k = np.clip(np.searchsorted(run.t, t), 0, run.t.size - 1)
        tension = np.mean(run.tension[k], axis=1)
        strain = np.sum(run.plastic[k], axis=1) / max(float(np.sum(run.rest_length)), 1e-9)
        pos = np.array([d.path.position(x) for x in t])
        pos2 = np.array([d.path.position(x + 0.5) for x in t])
        speed = np.hypot(*(pos2 - pos).T) / 0.5
        depth = np.hypot(*(pos - d.path.position(0.0)).T)
        touch = np.flatnonzero(lab > 0)
        t0 = t[touch[0]] if touch.size else t[0]
        for fi in range(t.size):
            sel = d.point_frame == fi
            if not sel.any():
                continue
            frame_t.append((t[fi] - t0) / max(t[-1] - t0, 1e-9))
            frame_sys.append(_sys(r.profile[sel], sp))
            frame_feat.append((tension[fi], speed[fi], strain[fi], depth[fi]))
    ph = np.concatenate(ph_all)
    for i, name in enumerate(PHASES):
        sel = ph == i
        if sel.any():
            ph_sys[name] = _sys(prof[sel], sp)
    out["when"] = ph_sys
    tot = sum(ph_sys.values()) or 1.0
    out["before_contact"] = ph_sys.get("approach", 0.0) / tot
    ft, fs, ff = np.array(frame_t), np.array(frame_sys), np.array(frame_feat)
    after = ft >= 0
    early = fs[after & (ft < 1 / 3)]
    late = fs[after & (ft >= 2 / 3)]
    ratio = ((float(np.mean(late)) + 1e-12) / (float(np.mean(early)) + 1e-12)
             if early.size and late.size else 1.0)
    out["trend"] = {"late_over_early": ratio,
                    "kind": ("growing" if ratio > 1.5 else "decaying" if ratio < 0.67
                             else "constant")}
    out["proportional_to"] = {name: _corr(fs, ff[:, k]) for k, name in
                              enumerate(("tension", "speed", "strain", "position"))}
    # force: lag and gain of the residual against the model force
    lag = gain = None
    share_x = None
    if forces:
        rr, mf, md = [], [], []
        for d, r in zip(data, res):
            if r.force is None:
                continue
            m = d.record.wrench_xz - r.force
            rr.append(r.force)
            mf.append(m)
            md.append(np.gradient(m, d.record.wrench_t, axis=0))
        r_all, mf_all, md_all = (np.concatenate(x).reshape(-1) for x in (rr, mf, md))
        X = np.c_[mf_all, md_all]
        coef, *_ = np.linalg.lstsq(X, r_all, rcond=None)
        gain, lag = float(coef[0]), float(-coef[1])
        fx = np.concatenate([r.force[:, 0] for r in res if r.force is not None])
        fz = np.concatenate([r.force[:, 1] for r in res if r.force is not None])
        share_x = _sys(fx, sf) / max(_sys(fx, sf) + _sys(fz, sf), 1e-12)
        out["force_explained_by_gain_and_lag"] = float(
            1.0 - np.sum((r_all - X @ coef) ** 2) / max(np.sum(r_all ** 2), 1e-30))
    out["force_lag_s"] = lag
    out["force_gain"] = gain
    out["force_x_share"] = share_x
    prof_mean = float(np.mean(prof))
    out["profile_mean_m"] = prof_mean
    out["profile_offset_share"] = abs(prof_mean) / max(_sys(prof, sp), 1e-12)
    out["partial_substitutes"] = dict(partial or {})
    out["causes"] = rank_causes(out)
    return out


def rank_causes(sig: dict) -> list[dict]:
    """Kinds of cause ranked by a score in [0, ~1] from the signature's features."""
    obs = sig["observables"]
    ep = max(obs.get("profile", 0.0), 0.0)
    ef = max(obs.get("tool force", 0.0), 0.0)
    force_share = ef / (ep + ef) if ep + ef > 0 else 0.0
    prop = sig["proportional_to"]
    when = sig["when"]
    tot = sum(when.values()) or 1.0
    late = (when.get("dwell", 0.0) + when.get("release", 0.0) + when.get("settle", 0.0)) / tot
    moving = when.get("forced deformation", 0.0) / tot
    before = sig.get("before_contact", 0.0)
    band = sig["where"]["peak_band"]
    trend = sig["trend"]["kind"]
    fx = sig.get("force_x_share") or 0.0
    chain_like = sig.get("force_explained_by_gain_and_lag") or 0.0
    scores = {
        "contact friction": 0.4 * late + 0.3 * fx + 0.3 * force_share,
        "rate-dependent rheology": (0.4 * max(prop["speed"], 0.0) + 0.3 * moving
                                    + 0.3 * (trend == "decaying")),
        "strain-dependent material": (0.4 * (trend == "growing") + 0.3 * max(prop["strain"], 0.0)
                                      + 0.3 * late),
        "bending stiffness": 0.5 * before + 0.3 * (band == 0) + 0.2 * (1 - force_share),
        "mass or gravity load": (0.6 * before + 0.2 * (1 - force_share)
                                 + 0.2 * (trend == "constant")),
        "tool position calibration": (0.4 * max(prop["position"], 0.0) + 0.3 * force_share
                                      + 0.3 * (1 - before)),
        "measurement chain": 0.5 * chain_like * force_share + 0.5 * min(
            sig.get("profile_offset_share", 0.0), 1.0) * (1 - force_share),
    }
    partial = sig.get("partial_substitutes") or {}
    lead = {k: v for k, v in partial.items() if v >= SUBSTITUTE_SHARE}
    ranked = sorted(scores.items(), key=lambda kv: (-lead.get(kv[0], -1.0), -kv[1]))
    return [{"kind": k, "score": float(v), "substitute_share": partial.get(k)}
            for k, v in ranked]
