"""The compiled sheet step caches its machine code in the user's cache directory, so a
read-only install (colcon prefix, site-packages) compiles once per user, not every run.

The package is copied into a read-only tree and imported from there in a fresh process
with an empty temporary HOME; when the tests run as root (who may write anywhere) the tree
is bind-mounted read-only for that process (a private mount namespace, ``unshare``), so
it is really read-only to it.
"""
from __future__ import annotations

import os
import shutil
import stat
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

import rheo_shaping

STEP = """
import sys
sys.path.insert(0, sys.argv[1])
import numpy as np
import rheo_shaping
assert rheo_shaping.__file__.startswith(sys.argv[1]), rheo_shaping.__file__
from rheo_shaping.sheet.geometry import Workplane
from rheo_shaping.sheet.chain import ChainConstants, Obstacle, SheetModel
n = 5
c = ChainConstants(anchor_top=np.array([0.0, 0.1]), anchor_bottom=np.array([0.1, 0.1]),
                   rest_length=np.full(n + 1, 0.02), k1=np.full(n + 1, 500.0),
                   c1=np.zeros(n + 1), c2=np.full(n + 1, np.inf), mass=np.full(n, 1e-3),
                   radius=1e-3)
model = SheetModel(c, [Obstacle("workplane", Workplane())])
x0 = np.column_stack((np.linspace(0.0, 0.1, n + 2)[1:-1], np.full(n, 0.1)))
st = model.step(model.initial_state(x0), 10.0, dynamic=False)
assert np.all(st.x[:, 1] < 0.1) and st.newton_iterations > 0
import os
print("CACHE_DIR", os.environ["NUMBA_CACHE_DIR"])
"""


def _read_only_copy(dest: Path) -> Path:
    pkg = Path(rheo_shaping.__file__).resolve().parent
    shutil.copytree(pkg, dest / "rheo_shaping",
                    ignore=shutil.ignore_patterns("__pycache__", "*.pyc", "nodes"))
    for root, dirs, files in os.walk(dest):
        for f in files:
            os.chmod(Path(root) / f, 0o444)
        os.chmod(root, 0o555)
    return dest


def _run(site: Path, home: Path, user: list[str], debug: bool) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items()
           if k not in ("NUMBA_CACHE_DIR", "XDG_CACHE_HOME", "PYTHONPATH")}
    env["HOME"] = str(home)
    env["PYTHONDONTWRITEBYTECODE"] = "0"
    if debug:
        env["NUMBA_DEBUG_CACHE"] = "1"
    return subprocess.run(user + [sys.executable, "-c", STEP, str(site)], env=env, cwd=home,
                          capture_output=True, text=True, timeout=900)


def test_compiled_step_is_cached_in_the_user_cache_dir_of_a_read_only_install():
    # not pytest's tmp_path: its parents are private to the user running the tests
    with tempfile.TemporaryDirectory(prefix="rheo-kernel-cache-") as tmp:
        tmp_path = Path(tmp)
        os.chmod(tmp_path, 0o755)
        try:
            _check_cache(tmp_path)
        finally:
            for root, dirs, files in os.walk(tmp_path):
                os.chmod(root, 0o755)


def _check_cache(tmp_path: Path) -> None:
    site = _read_only_copy(tmp_path / "site")
    home = tmp_path / "home"
    home.mkdir()
    user: list[str] = []
    if os.geteuid() == 0:
        unshare = shutil.which("unshare")
        probe = subprocess.run([unshare or "unshare", "--mount", "true"], capture_output=True) \
            if unshare else None
        if probe is None or probe.returncode != 0:
            pytest.skip("running as root without unshare --mount: cannot make the install "
                        "read-only")
        # the tree given as the last argument is bind-mounted read-only, then python runs
        user = [unshare, "--mount", "sh", "-c",
                'for a; do site="$a"; done; mount --bind -o ro "$site" "$site" && exec "$@"',
                "sh"]
    first = _run(site, home, user, debug=False)
    assert first.returncode == 0, first.stderr[-3000:]
    cache = home / ".cache" / "rheo_shaping" / "numba"
    assert f"CACHE_DIR {cache}" in first.stdout
    saved = sorted(p.name for p in cache.rglob("*.nbi"))
    assert any(name.startswith("step.advance-") for name in saved), saved
    assert any(p.suffix == ".nbc" for p in cache.rglob("*.nbc"))
    # nothing was written into the install
    written = [p for p in site.rglob("*") if p.suffix in (".nbi", ".nbc")]
    assert written == []
    # a second run loads the step from that cache instead of compiling it
    second = _run(site, home, user, debug=True)
    assert second.returncode == 0, second.stderr[-3000:]
    log = second.stdout + second.stderr
    assert "data loaded from" in log and "advance" in log
    assert "data saved to" not in log, log[-2000:]
    mode = stat.S_IMODE(os.stat(site / "rheo_shaping").st_mode)
    assert mode == 0o555
    # another install of the same source (another prefix) finds the same cache: its folder
    # is named by the source's content, not by where the source lies
    other = _read_only_copy(tmp_path / "other-prefix")
    third = _run(other, home, user, debug=True)
    assert third.returncode == 0, third.stderr[-3000:]
    log = third.stdout + third.stderr
    assert "data loaded from" in log and "data saved to" not in log, log[-2000:]


def test_cache_folder_is_named_by_the_source_and_the_numba_version():
    # numba's index keeps one numba version's entries: venvs with two numbas (.venv-core,
    # .venv-noble) sharing a folder would recompile every run, each erasing the other's
    import numba

    from rheo_shaping.sheet import kernel
    name = kernel.cache_folder()
    assert name == f"rheo_shaping_{kernel.source_digest()}_numba{numba.__version__}"
