"""Variations of the dynamic world's model form (issue 46, point 1): the same cell written by
someone else, each variation switchable and drawn per case from a range a real cell
plausibly has.  With every variation off (:class:`FormParams` ``()``) the world is
bit-for-bit the dynamic world of issue 26.

The variations, by kind (``Variation``; sizes against the default form in
docs/diagnosis.md, "A family of worlds", measured by ``benchmarks/world_family.py``):

* laying / letting go: ``release_sweep`` [s], the hands let go along the sheet, not all
  at once: mass i's weight comes on from t = |sweep| i / (N - 1) (from the cake side
  when sweep > 0, from the workplane bond when < 0), each over the laying's ``let_go``;
* contact: ``mould_softness`` [-] and ``tool_softness`` [-], the cake (and workplane) and
  the tool's pad are that many times softer than the world's penalty contact (stiffness
  / factor, damping / sqrt(factor): the same damping ratio); a sponge cake of modulus
  ~20 kPa over a 2 cm deep layer, 5 cm wide, is ~5e4 N/m per m of sheet, 1000 times
  softer than the default 5e7;
* the sheet: ``thickness_variation`` [-], the relative RMS of a hand-rolled sheet's
  thickness along it (a smooth random profile of mean 1 from ``thickness_seed``): each
  link's stiffness and damping (k1, c1, c2) and each mass scale with the local
  thickness;
* sensors: ``load_cell_filter`` [s], the load cell's own first-order low-pass (its time
  constant, a dynamics no chain knob holds); ``tool_occlusion`` [m], the camera does not
  see the sheet where it touches the tool, nor where its surface is within this distance
  of the tool's (the tool hides it);
* damping: ``damping_scale`` [-], a factor on the air damping (3 1/s) and on the
  contact's damping ratio (0.5).
"""
from __future__ import annotations

import math
import random
from dataclasses import dataclass, fields, replace
from enum import Enum
from typing import Iterable

import numpy as np


class Variation(str, Enum):
    """A variation of the world's form (its :class:`FormParams` field)."""

    RELEASE_SWEEP = "release_sweep"
    MOULD_SOFTNESS = "mould_softness"
    TOOL_SOFTNESS = "tool_softness"
    THICKNESS_VARIATION = "thickness_variation"
    LOAD_CELL_FILTER = "load_cell_filter"
    TOOL_OCCLUSION = "tool_occlusion"
    DAMPING_SCALE = "damping_scale"


@dataclass(frozen=True)
class FormParams:
    """The world's form (defaults: every variation off, the dynamic world of issue 26)."""

    release_sweep: float = 0.0          # s, signed (see the module's docstring)
    mould_softness: float = 1.0         # cake and workplane contact stiffness divided by this
    tool_softness: float = 1.0          # the tool's contact stiffness divided by this
    thickness_variation: float = 0.0    # relative RMS of the sheet's thickness along it
    thickness_seed: int = 0             # the thickness profile's random seed
    load_cell_filter: float = 0.0       # s, the load cell's low-pass time constant
    tool_occlusion: float = 0.0         # m, the camera's blind distance (sheet to tool surface)
    damping_scale: float = 1.0          # factor on air damping and the contact damping ratio

    def __post_init__(self) -> None:
        checks = {"release_sweep": (-5.0, 5.0), "mould_softness": (1.0, 1e4),
                  "tool_softness": (1.0, 1e4), "thickness_variation": (0.0, 0.3),
                  "load_cell_filter": (0.0, 1.0), "tool_occlusion": (0.0, 0.02),
                  "damping_scale": (0.05, 20.0)}
        for name, (lo, hi) in checks.items():
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and lo <= v <= hi):
                raise ValueError(f"{name} = {v!r}: expected a number in {lo:g} to {hi:g}")
        if not isinstance(self.thickness_seed, int) or self.thickness_seed < 0:
            raise ValueError(f"thickness_seed = {self.thickness_seed!r}: expected an int >= 0")

    def active(self) -> list[Variation]:
        """The variations switched on (off: their default value)."""
        default = FormParams()
        return [v for v in Variation if getattr(self, v.value) != getattr(default, v.value)]

    def as_dict(self) -> dict:
        return {f.name: getattr(self, f.name) for f in fields(self)}


@dataclass(frozen=True)
class VariationRange:
    """Where a variation is drawn from: its kind, unit, range and how it is drawn."""

    variation: Variation
    kind: str                       # laying, contact, sheet, sensor, damping
    unit: str
    low: float
    high: float
    log: bool                       # drawn log-uniform (else uniform)
    signed: bool                    # a random sign
    why: str                        # the range's plausibility, one line

    def draw(self, rng: random.Random) -> float:
        """A value from the range (``rng``: a ``random.Random``)."""
        if self.log:
            v = math.exp(rng.uniform(math.log(self.low), math.log(self.high)))
        else:
            v = rng.uniform(self.low, self.high)
        return v * rng.choice((-1.0, 1.0)) if self.signed else v

    def at(self, x: float) -> float:
        """The value at quantile ``x`` (0-1) of the range as it is drawn (log or linear)."""
        if self.log:
            return math.exp(math.log(self.low) + x * (math.log(self.high) - math.log(self.low)))
        return self.low + x * (self.high - self.low)


VARIATIONS: dict[Variation, VariationRange] = {r.variation: r for r in (
    VariationRange(Variation.RELEASE_SWEEP, "laying", "s", 0.3, 1.5, False, True,
                   "two hands, or one hand sliding off, let go over a second"),
    VariationRange(Variation.MOULD_SOFTNESS, "contact", "-", 100.0, 2000.0, True, False,
                   "sponge or iced cake 5-100 kPa over 1-3 cm: 2.5e4-5e5 N/m per m"),
    VariationRange(Variation.TOOL_SOFTNESS, "contact", "-", 30.0, 1000.0, True, False,
                   "a silicone or foam pad on the tool, 1 mm to 1 cm thick"),
    VariationRange(Variation.THICKNESS_VARIATION, "sheet", "-", 0.04, 0.12, False, False,
                   "a rolling pin by hand: +-5-15 % thickness along a 10 cm strip"),
    VariationRange(Variation.LOAD_CELL_FILTER, "sensor", "s", 0.02, 0.15, True, False,
                   "a force sensor's anti-alias / averaging filter, 1-8 Hz corner"),
    VariationRange(Variation.TOOL_OCCLUSION, "sensor", "m", 0.5e-3, 3e-3, False, False,
                   "the tool hides the sheet under it, and its edge a little more"),
    VariationRange(Variation.DAMPING_SCALE, "damping", "-", 0.25, 4.0, True, False,
                   "air damping 0.75-12 1/s and contact damping ratio 0.12-2"),
)}


def check_variations(names: Iterable[str | Variation]) -> tuple[Variation, ...]:
    """The variations named (their values or enum members); ValueError naming the known ones."""
    out = []
    for n in names:
        try:
            out.append(Variation(n))
        except ValueError:
            raise ValueError(f"unknown world variation {n!r}: expected one of "
                             f"{', '.join(v.value for v in Variation)}") from None
    return tuple(out)


def draw_form(rng: random.Random, variations: Iterable[Variation],
              p_on: float = 0.5) -> FormParams:
    """A form with each of ``variations`` switched on with probability ``p_on`` and then drawn
    from its range (:data:`VARIATIONS`); the others off.  Always draws the same numbers per
    variation (on or off), so switching one does not move the others' draws."""
    kw: dict = {}
    chosen = set(check_variations(variations))
    for v in Variation:                         # a fixed order: the same draws each time
        on = rng.random() < p_on
        value = VARIATIONS[v].draw(rng)
        seed = rng.randrange(2 ** 31)
        if v in chosen and on:
            kw[v.value] = value
            if v is Variation.THICKNESS_VARIATION:
                kw["thickness_seed"] = seed
    return FormParams(**kw)


def stratified_form(seed: int, index: int, strata: int,
                    variations: Iterable[str | Variation]) -> FormParams:
    """Case ``index`` of ``strata`` calibration cases (a Latin hypercube over the family): each
    of ``variations`` off in half of the cases and on in the other half, its values there one
    to each of strata / 2 equal parts of its range (as drawn: log or linear), the cases
    shuffled per variation so that the variations' strata combine at random.  The cases then
    cover every variation's whole range, its ends included: 25 cases each drawn at random
    (:func:`draw_form`) held no mould softer than 1170 of 100-2000, and the floor calibrated
    on them read the soft mould's effect-free records as a gap."""
    chosen = set(check_variations(variations))
    if strata < 2:
        raise ValueError(f"strata = {strata}: expected 2 or more cases")
    kw: dict = {}
    for v in Variation:                         # a fixed order: the same draws each time
        perm = list(range(strata))
        random.Random(f"strata-{seed}-{v.value}").shuffle(perm)
        rng = random.Random(f"strata-{seed}-{v.value}-{index}")
        q = (perm[index % strata] + rng.random()) / strata
        sign = rng.choice((-1.0, 1.0))
        seed_v = rng.randrange(2 ** 31)
        if v in chosen and q >= 0.5:
            r = VARIATIONS[v]
            kw[v.value] = r.at(2.0 * q - 1.0) * (sign if r.signed else 1.0)
            if v is Variation.THICKNESS_VARIATION:
                kw["thickness_seed"] = seed_v
    return FormParams(**kw)


def case_form(seed: int, index: int, variations: Iterable[str | Variation] = (),
              always_on: Iterable[str | Variation] = (), strata: int = 0) -> FormParams:
    """The form of a benchmark's case ``index`` of ``seed``: ``variations`` each on with
    probability 1/2, ``always_on`` on; drawn from a random stream of the case's own (a
    string seed), so the case's other draws are those of the world without variations.
    ``strata`` > 0: ``variations`` stratified over that many cases instead
    (:func:`stratified_form`, a floor's calibration)."""
    on = check_variations(always_on)
    chosen = check_variations(variations)
    if not chosen and not on:
        return FormParams()
    form = (stratified_form(seed, index, strata, chosen) if strata > 0
            else draw_form(random.Random(f"form-{seed}-{index}"), chosen + on))
    if on:
        full = draw_form(random.Random(f"form-{seed}-{index}"), on, p_on=1.0)
        form = replace(form, **{v.value: getattr(full, v.value) for v in on},
                       **({"thickness_seed": full.thickness_seed}
                          if Variation.THICKNESS_VARIATION in on else {}))
    return form


def thickness_profile(form: FormParams, n_links: int) -> np.ndarray:
    """The sheet's relative thickness (n_links,) along it: 1 + rms f(s) / rms(f), f a sum of
    sines of wavelengths the strip's length / k (k = 1-6, amplitude 1/k, random phases from
    ``form.thickness_seed``), its mean set to exactly 1.  Ones when the variation is off."""
    if form.thickness_variation == 0.0:
        return np.ones(n_links)
    r = np.random.default_rng(form.thickness_seed)
    s = (np.arange(n_links) + 0.5) / n_links
    f = sum(np.sin(2.0 * math.pi * k * s + r.uniform(0.0, 2.0 * math.pi)) / k
            for k in range(1, 7))
    f = np.asarray(f, float) - float(np.mean(f))
    tau = 1.0 + form.thickness_variation * f / float(np.sqrt(np.mean(f * f)))
    return tau / float(tau.mean())


def low_pass(t: np.ndarray, x: np.ndarray, tau: float) -> np.ndarray:
    """First-order low-pass of samples ``x`` (K, ...) at times ``t`` (K,) [s], time constant
    ``tau`` [s] (the exact step response between samples, x held); ``x`` itself at 0."""
    if tau <= 0.0:
        return x
    y = np.empty_like(x)
    y[0] = x[0]
    a = 1.0 - np.exp(-np.diff(t) / tau)
    for k in range(1, t.size):
        y[k] = y[k - 1] + a[k - 1] * (x[k] - y[k - 1])
    return y
