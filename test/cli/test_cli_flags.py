"""Every rheo-shaping command: --version, --quiet and --json (issue 15)."""
from __future__ import annotations

import json
import subprocess
import sys

import pytest

import rheo_shaping
from rheo_shaping.cli import build_parser, main


def _subparsers():
    parser = build_parser()
    action = next(a for a in parser._actions if a.dest == "command")
    return action.choices


def test_version(capsys):
    with pytest.raises(SystemExit) as info:
        main(["--version"])
    assert info.value.code == 0
    assert capsys.readouterr().out.strip() == f"rheo-shaping {rheo_shaping.__version__}"


@pytest.mark.parametrize("name", sorted(_subparsers()))
def test_every_command_has_quiet_and_json(name):
    options = {o for a in _subparsers()[name]._actions for o in a.option_strings}
    assert "--quiet" in options and "--json" in options, (name, sorted(options))


def test_quiet_prints_nothing_and_json_still_prints(tmp_path, capsys):
    assert main(["simulate", "--movement", "2", "--quiet"]) == 0
    assert capsys.readouterr().out == ""
    assert main(["simulate", "--movement", "2", "--quiet", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["movement"] == 2


def test_a_cell_the_model_cannot_run_is_a_clear_error_not_a_traceback(tmp_path, capsys):
    """A value inside its range that the model cannot run (benchmarks/fuzz_bounds.py found
    movement.accel 5e-324 m/s^2: ruckig cannot plan it) ends with exit 2 and the reason on
    one line, naming the params file."""
    import yaml

    from rheo_shaping.params.config import dump_cell
    from rheo_shaping.params.cell import CellParams
    tree = yaml.safe_load(dump_cell(CellParams()))
    tree["/**"]["ros__parameters"]["movement"]["accel"] = 5e-324
    path = tmp_path / "slow.yaml"
    path.write_text(yaml.safe_dump(tree))
    assert main(["simulate", "--params", str(path), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("rheo-shaping simulate: error: the model cannot run this cell")
    assert str(path) in err and "RuckigError" in err and err.count("\n") == 1


@pytest.mark.parametrize("text, ns", [("", ""), ("/", ""), ("cell2", "/cell2"),
                                      ("/a/b_2", "/a/b_2"), (" /cellA ", "/cellA")])
def test_namespace_option_gives_an_absolute_ros_namespace(text, ns):
    from rheo_shaping.cli.common import ros_namespace
    assert ros_namespace(text) == ns


@pytest.mark.parametrize("text", ["2cell", "/cell-2", "//cell", "/cell/", "a b"])
def test_a_bad_namespace_is_named_with_what_was_expected(text):
    from rheo_shaping.cli import UserError
    from rheo_shaping.cli.common import ros_namespace
    with pytest.raises(UserError, match=r"^--namespace = .*: expected a ROS namespace"):
        ros_namespace(text)


def test_a_reader_that_goes_away_ends_the_command_quietly_not_with_a_traceback():
    # stdout is a pipe whose reader is already gone (`rheo-shaping simulate --json | head -c0`)
    code = ("import os, sys\n"
            "r, w = os.pipe(); os.close(r); os.dup2(w, 1)\n"
            "from rheo_shaping.cli import main\n"
            "sys.exit(main(['simulate', '--json']))\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=300)
    assert "Traceback" not in done.stderr and "BrokenPipeError" not in done.stderr
    assert done.returncode == 141, done.stderr
