"""The diagnosis's Markdown report: the verdict, the floor, the baseline, the candidates, the
signature, how far the gap shrinks and where (:func:`markdown`)."""
from __future__ import annotations

import math

import numpy as np


def _fmt(v, scale=1.0, digits=3):
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "n/a"
    return f"{v * scale:.{digits}f}"


def _sentence(text: str) -> str:
    """``text`` as a sentence: its first letter upper case (the rest as it is), a stop."""
    return text[:1].upper() + text[1:] + "."


def _g(v):
    return "n/a" if v is None or (isinstance(v, float) and not math.isfinite(v)) else f"{v:.4g}"


def markdown(diag, figures: dict, process: dict | None = None) -> str:
    """The report (see docs/diagnosis.md for every figure)."""
    from ..sheet.effects import EFFECTS
    from . import stats
    j = diag.to_json()
    lines = ["# Sim-to-real gap diagnosis", "",
             f"Records fitted: {', '.join(diag.records)}; "
             f"held out: {', '.join(diag.holdout) or 'none'}.",
             f"Noise estimated from the records: profile {diag.noise.profile_m * 1e3:.3f} mm, "
             f"tool force {diag.noise.force_N:.4f} N. Balanced misfit (1 = within noise; "
             f"profile and tool force weigh one half each): nominal J0 = {diag.J0:.3f} on the "
             f"fit records ({_fmt(diag.J0_holdout)} holdout), "
             f"calibrated baseline {diag.J_base:.3f} "
             f"({_fmt(diag.J_base_holdout)} holdout).", "",
             f"## Verdict: **{diag.verdict_name}**", ""]
    fl = diag.floor
    model_form = fl.model_form
    q95 = fl.q95_fit if model_form else stats.null_quantile()
    lines.append(f"Gap test: the baseline's excess J - 1 = {diag.J_base - 1:.4f} against "
                 f"effect-free records (95 % of them stay below "
                 f"{_fmt(q95, 1, 4)}): p_gap = {diag.p_gap:.3g}.")
    ini = diag.initial_state or {}
    cmp = ini.get("compared")
    if cmp is not None:
        motion = np.median([r.get("motion_noise_units", 0.0) for r in ini["records"].values()])
        lines.append(f"Initial state from the records: the sheet hardly moves before the tool "
                     f"touches (median {motion:.1f} noise units), as a settled sheet and one "
                     f"laid close to its resting shape both do. The baseline from the "
                     f"settled drape leaves J = {cmp['settled_J']:.3f}, from the first frame's "
                     f"sheet released J = {cmp['laid_J']:.3f}: the models start "
                     f"{'laid' if ini.get('mode') == 'laid' else 'settled'}.")
    elif ini.get("mode") in ("laid", "mixed"):
        laid = [r for r in ini["records"].values() if r.get("mode") == "laid"]
        lines.append(f"Initial state from the records: {len(laid)} record(s) begin with the "
                     f"sheet moving before the tool touches (median "
                     f"{np.median([r['motion_noise_units'] for r in laid]):.1f} noise units), "
                     f"so their models start from the first frame's sheet, released then, "
                     f"with the laid length {laid[0]['laid_length_m'] * 1e3:.2f} +- "
                     f"{laid[0]['laid_length_sd_m'] * 1e3:.2f} mm (median over the records).")
    if model_form:
        b = fl.baseline
        lines.append(f"Floor ({fl.source}; {fl.config}): what the baseline leaves on "
                     f"effect-free records of a simulator of another form, 95 % below "
                     f"J - 1 = {_fmt(fl.q95_fit, 1, 4)} (profile "
                     f"{_fmt(fl.q95_profile_m, 1e3, 3)} mm, tool force "
                     f"{_fmt(fl.q95_force_N, 1e3, 2)} mN). The baseline leaves "
                     f"{b.J_minus_1:.4f} ({_fmt(b.noise_units, 1, 2)} noise units; profile "
                     f"{_fmt(b.profile_systematic_m, 1e3, 3)} mm, tool force "
                     f"{_fmt(b.force_systematic_N, 1e3, 2)} mN)"
                     + ("; below the practical tolerance, not worth naming." if
                        fl.below_tolerance else "."))
        if fl.verdict is not None:
            v = fl.verdict
            lines.append(f"The verdict leaves {v.J_minus_1:.4f} ({_fmt(v.noise_units, 1, 2)} "
                         f"noise units; profile {_fmt(v.profile_systematic_m, 1e3, 3)} mm, tool "
                         f"force {_fmt(v.force_systematic_N, 1e3, 2)} mN): "
                         + ("beyond the floor: the named cause explains most of the gap, and "
                            "something the library does not hold remains beside it."
                            if v.beyond_floor else "within the floor."))
        if fl.naming is not None:
            n = fl.naming
            lines.append(f"Naming rule: explains {_fmt(n.explained_fit, 100, 0)} % of the "
                         f"baseline's excess (fit), {_fmt(n.explained_holdout, 100, 0)} % "
                         f"(holdout); best other effect {n.runner_up}: "
                         f"{_fmt(n.runner_up_explained_fit, 100, 0)} %; its remainder over "
                         f"the named one's {_fmt(n.remainder_ratio, 1, 1)} (asked "
                         f">= {n.rule.ratio:g}).")
    if diag.J_replay[0] is not None:
        y = np.asarray(diag.J_replay[0])
        lines.append(f"The written cell has a Kelvin dashpot (c1 > 0), whose force follows the "
                     f"tool's speed. Records of the baseline itself, at these records' stamps "
                     f"and pose noise, misfit their replay by J_replay = {np.median(y):.4f} "
                     f"(median of {y.size} draws of the pose noise, {y.min():.4f}-{y.max():.4f})."
                     f" The stored null holds no such cell, so the gap test and the adequacy "
                     f"checks compare with the null plus these draws (95 % below "
                     f"{stats.null_quantile(shift=y):.4f}).")
    vf = diag.verdict_fit
    if vf:
        pv = f"{vf.p:.3g}" if vf.p > 0 else "< 1e-300"
        lines.append(f"Strength: likelihood ratio {vf.LR:.1f} on {vf.k} parameter(s), p = {pv} "
                     f"(Bonferroni over the candidates"
                     + ("; reported, not asked: against a model-form floor the naming rule "
                        "decides" if model_form else "")
                     + f"); what it leaves: J - 1 = {vf.J - 1:.4f} "
                     f"(fit), "
                     f"{_fmt(vf.J_holdout - 1 if math.isfinite(vf.J_holdout) else None, 1, 4)} "
                     "(holdout).")
        b = diag.numerics_base
        if math.isfinite(vf.J_num_perp) and b is not None:
            from .check import GAP_SHARE, NUMERICS_FACTOR
            how = ("2 N + 1 masses, half steps" if vf.refinement == "chain and steps"
                   else "half steps; the finer chain did not run")
            lines.append(f"Numerics: the verdict's run refined ({how}) moves "
                         f"by J_num = {vf.J_num:.4f} ({vf.J_num_perp:.4f} that no refit absorbs; "
                         f"holdout {_fmt(vf.J_num_holdout, 1, 4)}), the baseline's by "
                         f"{_fmt(b.J_num, 1, 4)} ({_fmt(b.J_num_perp, 1, 4)}); the verdict's "
                         f"change less the baseline's: J_num_added = {_fmt(vf.J_num_added, 1, 4)} "
                         f"(holdout {_fmt(vf.J_num_added_holdout, 1, 4)}).  What the verdict "
                         f"leaves may exceed the effect-free null by {NUMERICS_FACTOR:.1f} x "
                         "J_num_added (the coarse model's own discretisation error at the "
                         f"effect), at most {GAP_SHARE * 100:.0f} % of the baseline's excess; "
                         "the interval includes the value error the refinement implies.")
        lines.append("")
        for n, vals in vf.values.items():
            e = EFFECTS[n]
            for k, v in enumerate(vals):
                lo, hi = vf.interval[n][k]
                lines.append(f"- {n}.{e.fit[k]} = {v:.4g} {e.unit[k]} (95 % interval {lo:.4g} .. "
                             f"{hi:.4g})")
    elif diag.verdict == "none":
        lines.append("The calibrated baseline agrees with the records as well as it does on "
                     "effect-free records: no effect is named.")
    elif diag.verdict == "measurement chain":
        lines.append("The gap lies in the measurement chain: with its values beyond their "
                     "tolerances (" + ", ".join(diag.side["chain_outside"]) + ") the baseline "
                     "explains the records; no effect of the sheet is named.")
    else:
        lines.append("No candidate accounts for what the baseline leaves (significant and "
                     "adequate on fit and holdout records): see the signature below.")
    held = ("The sheet knobs are held as the scenario writes them (`--baseline held`: the "
            "scenario is taken for a calibrated cell); only the measurement chain is fitted."
            if diag.baseline_mode == "held" else "")
    lines += ["", "## Baseline: what a careful user knows within a tolerance", "",
              (held + " " if held else "") + _sentence(diag.baseline_took_text()), "",
              "| knob | written | fitted | in tolerances | outside |", "|---|---|---|---|---|"]
    for name, b in diag.baseline.items():
        lines.append(f"| {name} | {_g(b.get('written'))} | {_g(b['value'])} {b['unit']} | "
                     f"{b['u']:+.2f} | {'yes' if b['outside'] else ''} |")
    cc = diag.side["chain_candidate"]
    lines += ["", "## Which side of the sensors", "",
              f"Side: **{diag.side['side']}**. The measurement chain beyond its tolerances "
              f"({', '.join(cc['outside']) or 'none needed'}) leaves J = {cc['J']:.4f} "
              f"(holdout {_fmt(cc['J_holdout'])}), p = {_g(cc['p'])}, "
              f"adequate: {cc['adequate']}.", ""]
    tm = diag.side.get("timing")
    if tm:
        lines += [(f"The load cell would lag by {tm['force_lag_s']:.3g} s; the profile lags "
                   f"the model by {tm['profile_lag_s']:.3g} s while the tool drives it. "
                   + ("A lag the camera sees too is not the load cell's: the tool follows its "
                      "reported pose late (or the camera's stamps run early), which neither "
                      "the chain nor the library holds." if tm["tool_lags"] else
                      "The profile does not lag with it (under "
                      f"{tm['profile_share']:.2g} of the force's lag): the load cell's own.")),
                  ""]
    lines += ["## Candidates", "",
              "| rank | effect | parameters | J fit | J holdout | LR | p | adequate | checked |",
              "|---|---|---|---|---|---|---|---|---|"]
    for e in j["effects"]:
        params = "; ".join(f"{n} = " + ", ".join(f"{v:.4g}" for v in vals)
                           for n, vals in e["params"].items())
        lines.append(f"| {e['rank']} | {e['name']} | {params} | {e['J_fit']:.4f} | "
                     f"{_fmt(e['J_holdout'], 1, 4)} | {_fmt(e['LR'], 1, 1)} | {_g(e['p'])} | "
                     f"{e['adequate']} | {e['checked']} |")
    if diag.signature:
        sig = diag.signature
        lines += ["", "## Signature of what the baseline leaves", "",
                  "- observables (excess J - 1): " + ", ".join(
                      f"{k} {v:.4f}" for k, v in sig["observables"].items()),
                  f"- along the sheet: peaks in arc-length band "
                  f"{sig['where']['peak_band'] + 1} of 5 "
                  f"(fraction {sig['where']['peak_band_arc_fraction'][0]:.1f}-"
                  f"{sig['where']['peak_band_arc_fraction'][1]:.1f} from the cake-top bond)",
                  "- in the process: "
                  + ", ".join(f"{k} {v * 1e3:.3f} mm" for k, v in sig["when"].items())
                  + f" (before contact: {sig['before_contact'] * 100:.0f} %)",
                  f"- in time: {sig['trend']['kind']} "
                  f"(late / early {sig['trend']['late_over_early']:.2f})",
                  "- correlation with: " + ", ".join(f"{k} {v:+.2f}" for k, v in
                                                     sig["proportional_to"].items()),
                  f"- tool force: lag {_g(sig['force_lag_s'])} s, gain {_g(sig['force_gain'])}",
                  "", "Kinds of cause, ranked (feature score; share of the gap a library "
                  "effect of that kind imitates on its own, which ranks a kind first from "
                  "30 %): " + ", ".join(
                      f"{c['kind']} ({c['score']:.2f}"
                      + (f"; {c['substitute_share'] * 100:.0f} %"
                         if c.get("substitute_share") is not None else "") + ")"
                      for c in sig["causes"]), ""]
    lines += ["", "## How far the gap shrinks", "",
              "| records | figure | nominal | baseline | verdict |", "|---|---|---|---|---|"]
    for grp in ("fit", "holdout"):
        b, m, a = (diag.gap_before.group(grp), diag.gap_baseline.group(grp),
                   diag.gap_after.group(grp))
        if b is None or m is None or a is None:
            continue
        for key, label, s in (("profile_rms_m", "profile RMS [mm]", 1e3),
                              ("profile_systematic_m", "profile systematic RMS [mm]", 1e3),
                              ("profile_max_rel", "profile max / undeformed length [%]", 100),
                              ("force_rms_N", "tool force RMS [N]", 1),
                              ("force_systematic_N", "tool force systematic RMS [N]", 1),
                              ("delta_error_m", "Delta error [mm]", 1e3),
                              ("gap", "gap beyond noise sqrt(J - 1)", 1)):
            if getattr(b, key) is not None:
                lines.append(f"| {grp} | {label} | {_fmt(getattr(b, key), s)} | "
                             f"{_fmt(getattr(m, key), s)} | {_fmt(getattr(a, key), s)} |")
        lines.append(f"| {grp} | shrink of the gap | | {_fmt(m.shrink)} | {_fmt(a.shrink)} |")
    if process:
        lines += ["", "## What the corrected model changes for the process (movement 4)", "",
                  "| figure | nominal | corrected |", "|---|---|---|"]
        for key, label, s in (("F_max", "F_max [N]", 1), ("SF", "SF", 1),
                              ("delta", "Delta [mm]", 1e3), ("d_opt", "d_opt [mm]", 1e3)):
            lines.append(f"| {label} | {_fmt(process['nominal'].get(key), s)} | "
                         f"{_fmt(process['corrected'].get(key), s)} |")
    lines += ["", "## Where (calibrated baseline)", "",
              "| rank | kind | where | n | RMS | systematic RMS | x noise | mean |",
              "|---|---|---|---|---|---|---|---|"]
    for w in diag.where:
        s = 1e3 if w["unit"] == "m" else 1.0
        u = "mm" if w["unit"] == "m" else "N"
        lines.append(f"| {w['rank']} | {w['kind']} | {w['name']} | {w['n']} | "
                     f"{_fmt(w['rms'], s)} {u} | {_fmt(w['systematic_rms'], s)} {u} | "
                     f"{_fmt(w['relative'], 1, 2)} | {_fmt(w['mean'], s)} {u} |")
    lines += ["", "## Figures", ""]
    for title, name in figures.items():
        lines.append(f"![{title}]({name})")
    lines.append("")
    lines.append(f"{diag.runs} simulations.")
    return "\n".join(lines) + "\n"
