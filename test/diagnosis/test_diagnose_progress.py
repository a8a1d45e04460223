"""``diagnose`` shows its progress as "stage k of n", each stage's total known when it
begins (so the ETA does not reset, issue 28); a record whose nominal model already fits
says so instead of "baseline took nan %"."""
from __future__ import annotations

import math
from types import SimpleNamespace

from rheo_shaping.cli.diagnose import _Progress
from rheo_shaping_validation.benchmark import base_cell, make_case
from rheo_shaping.diagnosis.engine import diagnose
from rheo_shaping.diagnosis.evaluate import STAGES
from rheo_shaping.diagnosis.result import Diagnosis


class Log:
    """A progress display that keeps what the engine told it."""

    def __init__(self):
        self.stages = []          # [k, n, name, total, expected, done]

    def stage(self, k, n, name, total):
        self.stages.append([k, n, name, total, 0, 0])

    def expect(self, n):
        self.stages[-1][4] += n

    def __call__(self, n):
        self.stages[-1][5] += n


def test_each_stage_is_announced_with_its_total_before_its_simulations():
    case = make_case(1, "none", 7, base_cell(31, 70.0))
    log = Log()
    d = diagnose(case["records"][:2], case["records"][2:], jobs=2, progress=log,
                 floor="numerics", initial_state="settled")
    ks = [s[0] for s in log.stages]
    names = [s[2] for s in log.stages]
    assert ks == sorted(set(ks)), ks       # a settled cell: no laid sheet's stages
    assert names[:3] == ["nominal models", "baseline Jacobian", "baseline fit"], names
    assert all(s[1] == len(STAGES) and s[2] == STAGES[s[0] - 1] for s in log.stages)
    for k, _n, name, total, expected, done in log.stages:
        assert expected == done > 0, name
        if name != "candidate checks":
            assert total is not None and done <= total, (name, total, done)
    n_rec = len(case["records"])
    assert log.stages[0][3] == log.stages[0][5] == n_rec      # the nominal model of each record
    assert sum(s[5] for s in log.stages) == d.runs


def test_the_bar_of_a_stage_keeps_its_total(capsys):
    p = _Progress(quiet=False)
    p.stage(1, 7, "nominal models", 4)
    totals = []
    for _ in range(2):
        p.expect(2)
        p(2)
        totals.append(p.bar.total)
    p.stage(6, 7, "candidate checks", None)
    p.expect(3)
    p(3)
    p.expect(5)
    assert p.bar.total == 8
    p(1)
    p.close()
    err = capsys.readouterr().err
    assert totals == [4, 4]
    assert "diagnose: stage 1 of 7, nominal models" in err and "4/4" in err
    assert "stage 6 of 7, candidate checks (total grows)" in err
    assert err.replace("\r", "\n").strip().splitlines()[-1].split("|")[-1].startswith(" 4/4"), \
        "a stage that ran short of its total closes at what it ran"


def test_baseline_of_a_record_that_already_fits_says_so():
    fits = SimpleNamespace(J0=0.97, J_base=0.96, baseline_took=math.nan)
    text = Diagnosis.baseline_took_text(fits)
    assert "nan" not in text and "already fits within the noise" in text
    gap = SimpleNamespace(J0=3.0, J_base=1.5, baseline_took=0.75)
    assert Diagnosis.baseline_took_text(gap).startswith("the baseline took 75.0 %")


def test_the_report_writes_it_as_a_sentence_with_its_symbols():
    from rheo_shaping.diagnosis.report_text import _sentence
    assert _sentence("the baseline took 5 % (J - 1: 2 -> 1)") == \
        "The baseline took 5 % (J - 1: 2 -> 1)."
