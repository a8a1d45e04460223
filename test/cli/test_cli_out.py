"""Every subcommand's ``--out``: a path that cannot be the folder it writes is a one-line
error naming the option, the path and what was expected, never a traceback (issue 28)."""
from __future__ import annotations

import os
import tempfile
from pathlib import Path

import pytest

from rheo_shaping.cli import build_parser, main


def _commands_with_out() -> list[str]:
    parser = build_parser()
    action = next(a for a in parser._actions if a.dest == "command")
    return sorted(name for name, sp in action.choices.items()
                  if any("--out" in a.option_strings for a in sp._actions))


#: The other arguments each command needs to reach its --out check (nothing is read
#: before it: the check comes first).
REQUIRED = {
    "diagnose": ["no-such-record"],
    "import-csv": ["--scenario", "s.yaml", "--pose", "p.csv", "--profile", "q.csv"],
}


def test_the_commands_with_out_are_the_ones_this_file_knows():
    assert _commands_with_out() == ["diagnose", "import-csv", "record", "record-cell",
                                    "reproduce"]


def _run(capsys, command: str, out: Path, *extra: str) -> str:
    code = main([command, *REQUIRED.get(command, []), "--out", str(out), "--quiet", *extra])
    err = capsys.readouterr().err
    assert code == 2, (command, out, err)
    assert "Traceback" not in err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    line = lines[0]
    assert line.startswith(f"rheo-shaping {command}: error: --out {out}"), line
    return line


@pytest.mark.parametrize("force", [False, True])
@pytest.mark.parametrize("command", _commands_with_out())
def test_out_an_existing_file(tmp_path, capsys, command, force):
    afile = tmp_path / "afile"
    afile.write_text("not a folder\n")
    line = _run(capsys, command, afile, *(["--force"] if force else []))
    assert "is an existing file, not a folder; expected" in line and "folder" in line
    assert afile.read_text() == "not a folder\n", "the file is left as it was"


@pytest.mark.parametrize("command", _commands_with_out())
def test_out_under_a_file(tmp_path, capsys, command):
    afile = tmp_path / "afile"
    afile.write_text("")
    line = _run(capsys, command, afile / "sub" / "out")
    assert f"{afile} is a file, not a folder; expected" in line


@pytest.mark.parametrize("command", _commands_with_out())
def test_out_under_a_missing_folder(tmp_path, capsys, command):
    line = _run(capsys, command, tmp_path / "missing" / "out")
    assert f"folder {tmp_path / 'missing'} does not exist; expected" in line


def _unwritable_folder(tmp_path: Path) -> Path:
    """A folder this process cannot create files in: a mode-0555 one for a normal user;
    as root (who writes there anyway) /sys, which refuses new files to everyone."""
    if os.geteuid() != 0:
        ro = tmp_path / "read-only"
        ro.mkdir()
        ro.chmod(0o555)
        return ro
    for place in ("/sys", "/proc"):
        try:
            fd, probe = tempfile.mkstemp(dir=place)
        except OSError:
            return Path(place)
        os.close(fd)
        os.unlink(probe)
    pytest.skip("no folder here refuses root a new file")


@pytest.mark.parametrize("command", _commands_with_out())
def test_out_in_a_folder_that_cannot_be_written(tmp_path, capsys, command):
    ro = _unwritable_folder(tmp_path)
    try:
        line = _run(capsys, command, ro / "out")
        assert f"cannot write in folder {ro} (" in line and "expected" in line
        assert "writable folder" in line
    finally:
        if ro.is_relative_to(tmp_path):
            ro.chmod(0o755)


@pytest.mark.parametrize("command", ["import-csv", "record", "record-cell"])
def test_out_forced_onto_a_folder_that_is_not_a_record(tmp_path, capsys, command):
    """--force replaces a record only: any other folder is refused before the work (for
    record-cell, before it waits for a cell)."""
    (tmp_path / "keep.txt").write_text("x")
    line = _run(capsys, command, tmp_path, "--force")
    assert "folder exists and is not a record" in line and "expected a new record" in line
    assert (tmp_path / "keep.txt").read_text() == "x"


@pytest.mark.parametrize("command", ["diagnose", "reproduce"])
def test_out_an_existing_folder_that_cannot_be_written(tmp_path, capsys, command):
    """An existing (empty) folder: written into, so it must be writable itself."""
    ro = _unwritable_folder(tmp_path)
    if not ro.is_relative_to(tmp_path):
        pytest.skip("the root case: /sys is not empty, refused as such")
    try:
        line = _run(capsys, command, ro)
        assert f"cannot write in folder {ro} (" in line
    finally:
        ro.chmod(0o755)


def test_reproduce_creates_a_missing_out_folder_after_the_checks(tmp_path):
    """The helper's ``create``: the folder is made (and only it) once every check passed."""
    from rheo_shaping.cli.common import output_dir
    out = output_dir(str(tmp_path / "figs"), force=False, create=True)
    assert out == tmp_path / "figs" and out.is_dir() and not any(out.iterdir())
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".rheo-shaping-probe")]


@pytest.mark.parametrize("argv", [["simulate", "--movement", "2", "--plot"],
                                  ["diagnose", "no-such-record", "--write-scenario"]])
def test_file_options_refuse_a_folder_and_a_place_under_a_file(tmp_path, capsys, argv):
    """The file-writing options share the checks: a folder, or a name under a file."""
    afile = tmp_path / "afile"
    afile.write_text("")
    for target, says in ((tmp_path, "is a folder; expected a file name"),
                         (afile / "x.png", f"{afile} is a file, not a folder")):
        assert main([*argv, str(target), "--quiet"]) == 2
        err = capsys.readouterr().err
        assert len(err.strip().splitlines()) == 1 and says in err and str(target) in err, err
