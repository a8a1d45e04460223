"""The diagnosis's JSON stays what users read: ``rheo-shaping diagnose --json`` on a fixed
small case (two fit records and one holdout record of a finer true chain with a tool offset,
the command's defaults) gives the object captured in fixtures/diagnose_json.json, key for
key: numbers to a relative 1e-6 on the numpy 2 build it was captured with (.venv-core);
on another (the noble stage's numpy 1.26 and its BLAS: 1e-6 to 4e-5 relative apart) the
keys, types and strings only."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from _support.json_same import differences
from rheo_shaping.cli import main
from rheo_shaping_validation.benchmark import base_cell, make_case
from rheo_shaping.records.bag import write_record

FIXTURE = Path(__file__).resolve().parent / "fixtures" / "diagnose_json.json"


def test_diagnose_json_is_unchanged(tmp_path, capsys):
    case = make_case(4, "single", 3, base_cell(31, 70.0))
    paths = []
    for r in case["records"]:
        write_record(r, tmp_path / r.name)
        paths.append(str(tmp_path / r.name))
    code = main(["diagnose", paths[0], paths[1], "--holdout", paths[2], "--json", "--quiet",
                 "--jobs", "2"])
    assert code == 0
    out = json.loads(capsys.readouterr().out)
    assert out.pop("wall_time_s") > 0
    want = json.loads(FIXTURE.read_text())
    assert out["verdict"] == "tool_offset"             # the case names something
    captured_build = int(np.__version__.split(".")[0]) >= 2
    diff = differences(out, want, numbers=captured_build)
    assert not diff, "the diagnose JSON changed:\n" + "\n".join(diff[:20])
