"""``rheo-shaping identify``: in-process through rheo_shaping.cli.main, and once as a module."""
from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from importlib import resources
from pathlib import Path

import pytest

from rheo_shaping.cli import main
from rheo_shaping.material.three_element import maxwell
from rheo_shaping.identification.synthetic_material import synthetic_tensile_curve

REPO = Path(__file__).resolve().parents[2]
TABLE1 = str(resources.files("rheo_shaping") / "data" / "table1_creep.csv")
SYNTH = str(resources.files("rheo_shaping") / "data" / "synthetic_tensile_paper_params.csv")
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def run(capsys, *argv):
    code = main(["identify", *argv])
    out, err = capsys.readouterr()
    return code, out, err


def test_json_from_table1_only(capsys):
    code, out, err = run(capsys, "--creep", TABLE1, "--json")
    assert code == 0, err
    doc = json.loads(out)                             # exactly one JSON object
    assert abs(doc["c2"] / 1.30e3 - 1) < 0.01
    assert doc["se"]["c2"] == pytest.approx(15.52, rel=1e-3)
    lo, hi = doc["ci95"]["c2"]
    assert lo < 1300 < hi
    assert doc["k1"] is None and doc["se"]["k1"] is None and doc["ci95"]["k1"] is None
    assert doc["c1"] is None and doc["model"] is None
    assert doc["units"]["c2"] == "N s/m" and doc["method"] == "paper"


@pytest.mark.parametrize("method", ["paper", "joint"])
def test_json_with_a_tensile_curve(capsys, method):
    code, out, err = run(capsys, "--creep", TABLE1, "--tensile",
                         SYNTH, "--method", method, "--json")
    assert code == 0, err
    doc = json.loads(out)
    assert doc["model"] == "maxwell"
    assert abs(doc["k1"] / 95.0 - 1) < 0.02 and abs(doc["c2"] / 1300.0 - 1) < 0.02
    assert doc["c1"] == 0.0 and doc["ci95"]["c1"][0] == 0.0
    assert doc["k2"] is None                          # inf: no series spring
    assert doc["curves"][0]["crack_found"] is True
    if method == "joint":
        rows = {r["model"]: r for r in doc["model_choice"]["table"]}
        assert set(rows) == {"maxwell", "three-element", "burgers"}
        assert rows["maxwell"]["delta_bic"] == 0.0
        assert all(math.isfinite(r["aic"]) and math.isfinite(r["bic"]) for r in rows.values())


def test_human_output_is_a_table_with_units(capsys):
    code, out, err = run(capsys, "--creep", TABLE1, "--tensile", SYNTH)
    assert code == 0, err
    assert "N s/m" in out and "N/m" in out and "95 % interval" in out
    line = next(l for l in out.splitlines() if l.strip().startswith("c2"))  # noqa: E741
    assert "1299" in line


def test_speed_from_the_command_line_and_conflicts(capsys, tmp_path):
    s = synthetic_tensile_curve(maxwell(95.0, 1300.0), 2e-3, seed=4, F_break=math.inf, t_max=30.0)
    p = tmp_path / "fast.csv"
    lines = ["t_s,F_N"] + [f"{float(t)!r},{float(F)!r}" for t, F in zip(s.curve.t, s.curve.force)]
    p.write_text("\n".join(lines) + "\n")             # no speed metadata
    code, out, err = run(capsys, "--creep", TABLE1, "--tensile",
                         str(p), "--speed", "2e-3", "--json")
    assert code == 0, err
    assert abs(json.loads(out)["k1"] / 95.0 - 1) < 0.03
    code, out, err = run(capsys, "--creep", TABLE1, "--tensile", SYNTH, "--speed", "2e-3")
    assert code == 2 and "contradicts" in err and "line" in err
    code, out, err = run(capsys, "--creep", TABLE1, "--speed", "-1")
    assert code == 2 and "--speed" in err


def test_malformed_file_names_file_line_and_column(capsys, tmp_path):
    p = tmp_path / "creep.csv"
    p.write_text("# a comment\ntest,F_N,t1_s,x_residual_m\n1,0.5,60,0.023\n2,0.5,sixty,0.023\n")
    code, out, err = run(capsys, "--creep", str(p))
    assert code == 2 and out == ""
    assert str(p) in err and "line 4" in err and "column 3 (t1_s)" in err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1


def test_missing_file_names_its_path(capsys, tmp_path):
    missing = tmp_path / "nope" / "table.csv"
    code, out, err = run(capsys, "--creep", str(missing))
    assert code == 2 and str(missing) in err and "no such file" in err


def test_wrong_kind_of_file_for_the_option(capsys):
    code, out, err = run(capsys, "--creep", SYNTH)
    assert code == 2 and "--tensile" in err
    code, out, err = run(capsys, "--creep", TABLE1, "--tensile", TABLE1)
    assert code == 2 and "--creep" in err


def test_plot_is_written_and_never_overwritten_without_force(capsys, tmp_path):
    png = tmp_path / "fit.png"
    code, out, err = run(capsys, "--creep", TABLE1, "--tensile", SYNTH,
                         "--method", "joint", "--plot", str(png))
    assert code == 0, err
    assert png.read_bytes().startswith(PNG_MAGIC)
    png.write_bytes(b"keep me")
    code, out, err = run(capsys, "--creep", TABLE1, "--plot", str(png))
    assert code == 2 and str(png) in err and "--force" in err
    assert png.read_bytes() == b"keep me"
    code, out, err = run(capsys, "--creep", TABLE1, "--tensile",
                         SYNTH, "--plot", str(png), "--force")
    assert code == 0, err
    assert png.read_bytes().startswith(PNG_MAGIC)
    code, out, err = run(capsys, "--creep", TABLE1, "--plot", str(tmp_path / "no" / "dir.png"))
    assert code == 2 and "no such directory" in err


def _panels(fig) -> list[str]:
    return [ax.get_title() for ax in fig.axes]


def _title(fig) -> str:
    """The figure's title on one line (matplotlib 3.6, noble's, has no get_suptitle)."""
    (title,) = [t.get_text() for t in fig.texts]
    return title.replace("\n", " ")


def test_plot_draws_only_the_panels_it_has_data_for_under_a_title(capsys, tmp_path):
    """The README's example (creep table only) draws the creep panel alone, not three empty
    axes beside it, under a title that says what was identified and what is missing."""
    from rheo_shaping.identification.identification_plots import plot_joint, plot_paper
    from rheo_shaping.identification.material_data import (read_creep_residuals,
                                                           read_tensile_curve)
    from rheo_shaping.identification.model_choice import identify_joint
    from rheo_shaping.identification.paper_method import identify_paper
    png = tmp_path / "ident.png"
    code, out, err = run(capsys, "--creep", TABLE1, "--plot", str(png))
    assert code == 0, err
    assert png.read_bytes().startswith(PNG_MAGIC) and f"plot: {png}" in out
    creep = read_creep_residuals(TABLE1)
    tensile = [read_tensile_curve(SYNTH, None, 1e-3)]
    fig = plot_paper(identify_paper(creep), tmp_path / "p1.png")
    assert _panels(fig) == ["creep tests: residual elongation (Eq. 10)"]
    assert _title(fig) == (
        "identify, the paper's method (Sec. 3.4): c2 = 1299 N s/m; model: not determined "
        "no tensile curve: k1 and c1 (Eq. 5, Eq. 12-13) need one (--tensile FILE)")
    fig = plot_paper(identify_paper(creep, tensile), tmp_path / "p2.png", tensile)
    assert _panels(fig) == ["tensile curves (offset removed) and Eq. 5", "Eq. 12-13: Y + b X = 0",
                            "residuals F - Eq. 5", "creep tests: residual elongation (Eq. 10)"]
    assert _title(fig).startswith("identify, the paper's method (Sec. 3.4): c2 = 1299 "
                                  "N s/m, c1 = 0 N s/m, k1 = ")
    fig = plot_joint(identify_joint([], [creep], []), tmp_path / "j1.png")
    assert _panels(fig) == ["creep tests (Eq. 10)"]
    assert "no tensile curve: k1, c1 and the model need one (--tensile FILE)" in _title(fig)
    fig = plot_joint(identify_joint(tensile, [creep], []), tmp_path / "j2.png", tensile)
    assert len(_panels(fig)) == 5 and _panels(fig)[-1] == "creep tests (Eq. 10)"
    assert _title(fig).startswith("identify, joint fit (model chosen by BIC): maxwell;")


def test_as_a_module_in_a_subprocess():
    env = dict(os.environ, PYTHONPATH=str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    proc = subprocess.run([sys.executable, "-m", "rheo_shaping.cli", "identify", "--creep", TABLE1,
                           "--json"],
                          capture_output=True, text=True, cwd=REPO, env=env, timeout=60)
    assert proc.returncode == 0, proc.stderr
    doc = json.loads(proc.stdout)
    assert abs(doc["c2"] / 1300 - 1) < 0.01 and doc["se"]["c2"] > 0
    bad = subprocess.run([sys.executable, "-m", "rheo_shaping.cli", "identify", "--creep",
                          "/nonexistent.csv"],
                         capture_output=True, text=True, cwd=REPO, env=env, timeout=60)
    assert bad.returncode == 2 and "/nonexistent.csv" in bad.stderr
    assert "Traceback" not in bad.stderr
