"""A benchmark run: its cases, each its own seed, on an executor, resumable from its finished
cases (:mod:`.checkpoint`); the summary with every case's row (:func:`run_benchmark`)."""
from __future__ import annotations

import time
from concurrent.futures import Executor
from typing import Callable

from rheo_shaping.parallel import run_tasks
from rheo_shaping.sheet.effects import EFFECT_NAMES
from .cases import KINDS_PATTERN, NoCase, base_cell, make_case
from .checkpoint import append_partial, read_partial
from .score import score_case, summarise
from .world import WORLDS, check_world
from rheo_shaping_validation.worlds.forms import check_variations


def run_benchmark(n: int = 60, seed: int = 1, jobs: int | None = None,
                  progress: Callable[[int], None] | None = None, n_masses: int = 31,
                  process_time: float = 70.0, kinds: tuple[str, ...] | None = None,
                  executor: Executor | None = None, world: str = "finer-chain",
                  floor: str | None = None, initial_state: str | None = None,
                  partial: str | None = None, variations: tuple = (),
                  always_on: tuple = ()) -> dict:
    """Run ``n`` cases; returns the summary with every case under ``case_results``.
    ``variations`` / ``always_on``: the dynamic world's form variations drawn per case /
    switched on in every case (:func:`~rheo_shaping_validation.worlds.forms.case_form`).

    The cases go to ``executor`` (:mod:`rheo_shaping.parallel`: a local pool, a Dask
    cluster), each with its own seed (case i of seed s is the same wherever it runs);
    with no executor they run here, each diagnosis on ``jobs`` local processes.
    ``progress(k)``: k more cases done.  ``world``: which of :data:`WORLDS` makes the
    records.  ``partial``: a JSON-lines file [path] each finished case is appended to, and
    whose cases of the same benchmark (seed, world, chain, record length, floor, initial
    state) are not run again (an interrupted benchmark goes on where it stopped)."""
    opts = WORLDS[check_world(world)].options
    variations, always_on = check_variations(variations), check_variations(always_on)
    base = base_cell(n_masses, process_time)
    t0 = time.monotonic()
    pattern = tuple(kinds or KINDS_PATTERN)
    shared = {"seed": seed, "base": base, "pattern": pattern,
              "jobs": jobs if executor is None else 1, "world": world,
              "floor": floor or str(opts.floor),
              "initial_state": initial_state or opts.initial_state.value,
              "variations": tuple(variations), "always_on": tuple(always_on)}
    key = {"seed": seed, "world": world, "n_masses": n_masses, "process_time_s": process_time,
           **({"variations": [v.value for v in variations],
               "always_on": [v.value for v in always_on]} if variations or always_on else {}),
           "floor": shared["floor"], "initial_state": shared["initial_state"],
           "pattern": list(pattern)}
    done = read_partial(partial, key) if partial else {}
    if partial:
        shared.update(partial=str(partial), key=key)
    todo = [i for i in range(n) if i not in done]
    if progress is not None and n - len(todo):
        progress(n - len(todo))
    rows = run_tasks(executor, _case_task, shared, todo, progress,
                     chunks_per_worker=1 if executor is None else 2)
    rows = sorted([r for i, r in done.items() if i < n] + rows, key=lambda r: r["index"])
    undrawn = [r for r in rows if "no_case" in r]
    rows = [r for r in rows if "no_case" not in r]
    out = summarise(rows, time.monotonic() - t0)
    out["undrawn_cases"] = undrawn
    out["resumed_cases"] = len([i for i in done if i < n])
    true_n = WORLDS[world].true_n_masses(n_masses)
    out.update({"seed": seed, "world": world, "floor": shared["floor"],
                "variations": [v.value for v in variations],
                "always_on": [v.value for v in always_on],
                "initial_state": shared["initial_state"], "n_masses": n_masses,
                "true_n_masses": true_n,
                "process_time_s": process_time, "case_results": rows})
    return out


def library_for(case: dict) -> tuple[str, ...]:
    """The effects a case is diagnosed with: the library, less an out-of-library case's own
    effect when it is a library one (a world's own effect withholds nothing)."""
    if case["kind"] != "out_of_library":
        return EFFECT_NAMES
    return tuple(x for x in EFFECT_NAMES if x != case["truth"][0][0])


def _case_task(shared: dict, i: int) -> dict:
    """Case ``i``: its records (its own seed), the diagnosis, the score (module-level: it
    pickles to a worker)."""
    from rheo_shaping.diagnosis.engine import diagnose
    pattern = shared["pattern"]
    kind = pattern[i % len(pattern)]
    try:
        case = make_case(i, kind, shared["seed"], shared["base"],
                         world=shared.get("world", "finer-chain"),
                         variations=shared.get("variations", ()),
                         always_on=shared.get("always_on", ()))
    except NoCase as exc:                   # counted apart, never a case nor a crash
        row = {"index": i, "kind": kind, "no_case": str(exc)}
        if shared.get("partial"):
            append_partial(shared["partial"], shared["key"], row)
        return row
    library = library_for(case)
    t1 = time.monotonic()
    diag = diagnose(case["records"][:2], case["records"][2:], library=library,
                    jobs=shared["jobs"], floor=shared.get("floor", "numerics"),
                    initial_state=shared.get("initial_state", "settled"))
    row = score_case(case, diag)
    row["diagnosis_wall_s"] = time.monotonic() - t1
    row["library_size"] = len(library)
    if shared.get("partial"):
        append_partial(shared["partial"], shared["key"], row)
    return row
