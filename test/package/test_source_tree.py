"""No test writes into the source tree: ``colcon test`` runs pytest in the package's source
folder, and a user's ``git status --porcelain --ignored`` must stay as it was after it.

test/conftest.py compares the repository's untracked and ignored entries at the session's
start and end (``_support/source_tree.py``) and fails the session on a new one; here that
guard is run on a copy of the test set-up in a git repository of its own.
"""
from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

from _support.source_tree import added

TEST_DIR = Path(__file__).resolve().parents[1]


def _tree_with_a_test(tmp_path: Path, body: str) -> Path:
    """A git repository holding test/conftest.py, test/_support/ and one test of ``body``."""
    repo = tmp_path / "repo"
    (repo / "test").mkdir(parents=True)
    shutil.copy2(TEST_DIR / "conftest.py", repo / "test" / "conftest.py")
    shutil.copytree(TEST_DIR / "_support", repo / "test" / "_support",
                    ignore=shutil.ignore_patterns("__pycache__"))
    (repo / ".gitignore").write_text("log/\n__pycache__/\n.pytest_cache/\n")
    (repo / "test" / "test_one.py").write_text(
        "from pathlib import Path\n\n\ndef test_one(tmp_path):\n" + body)
    git = ["git", "-C", str(repo), "-c", "user.name=test", "-c", "user.email=test@invalid"]
    subprocess.run([*git, "init", "-q"], check=True)
    subprocess.run([*git, "add", "-A"], check=True)
    subprocess.run([*git, "commit", "-q", "-m", "tree"], check=True)
    return repo


def _pytest(repo: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "pytest", "-q", "--stage", "all",
                           "test/test_one.py"], cwd=repo, stdout=subprocess.PIPE,
                          stderr=subprocess.STDOUT, text=True, timeout=120)


def test_a_session_whose_test_writes_into_the_source_tree_fails(tmp_path):
    """What `colcon test-result` without a working directory did: log/ in the source folder."""
    repo = _tree_with_a_test(tmp_path, "    (Path('log') / 'latest').mkdir(parents=True)\n"
                                       "    (Path('log') / 'latest' / 'logger_all.log').touch()\n")
    proc = _pytest(repo)
    assert proc.returncode == 1, proc.stdout
    assert "1 passed" in proc.stdout
    assert ("a test wrote into the source tree (git status --porcelain --ignored):\n  !! log/"
            in proc.stdout), proc.stdout


def test_a_session_that_writes_only_into_its_temporary_folders_passes(tmp_path):
    repo = _tree_with_a_test(tmp_path, "    (tmp_path / 'log').mkdir()\n"
                                       "    (tmp_path / 'log' / 'logger_all.log').touch()\n")
    proc = _pytest(repo)
    assert proc.returncode == 0, proc.stdout
    assert "source tree" not in proc.stdout


def test_the_tools_caches_are_not_a_test_writing():
    before = {"!! .venv/"}
    after = before | {"!! test/__pycache__/", "!! .pytest_cache/", "?? out.png", "!! log/"}
    assert added(before, after) == ["!! log/", "?? out.png"]
