"""A real ``colcon build`` of the package, and what ``ros2 run`` would need from it.

Builds the repository with the venv's colcon into a temporary workspace
(isolated install, colcon's default: the package's prefix is
``<install>/rheo_shaping``), then checks the ament index, the installed
executables and data files, and that each node executable starts, shows up in
the ROS graph, and exits with code 0 on SIGINT.
"""
from __future__ import annotations

import os
import shlex
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytest.importorskip("colcon_core", reason="colcon is not installed: run in the full venv (.venv)")

REPO = Path(__file__).resolve().parents[2]
PACKAGE = "rheo_shaping"
NODES = ("simulator", "planner", "monitor", "gap_watch")
#: The managed executables (rheo_shaping/nodes/managed.py) and the node name each starts.
MANAGED = {"simulator_managed": "simulator", "planner_managed": "planner",
           "monitor_managed": "monitor", "gap_watch_managed": "gap_watch",
           "lifecycle_manager": "lifecycle_manager"}
EXECUTABLES = (*NODES, *MANAGED, "rheo-shaping")
BUILD_TIMEOUT_S = 300
START_TIMEOUT_S = 30
STOP_TIMEOUT_S = 10


def _clean_env(**extra: str) -> dict[str, str]:
    """The test's environment without any sourced ROS workspace."""
    env = dict(os.environ)
    for var in ("AMENT_PREFIX_PATH", "COLCON_PREFIX_PATH", "CMAKE_PREFIX_PATH"):
        env.pop(var, None)
    env.update(extra)
    return env


def _colcon_cmd() -> list[str]:
    script = Path(sys.executable).with_name("colcon")
    if script.exists():
        return [sys.executable, str(script)]
    return [sys.executable, "-c", "import sys; from colcon_core.command import main; "
                                  "sys.exit(main())"]


@pytest.fixture(scope="module")
def workspace(tmp_path_factory) -> Path:
    """Run ``colcon build`` once for the module; return the workspace dir."""
    ws = tmp_path_factory.mktemp("colcon_ws")
    cmd = [
        *_colcon_cmd(), "--log-base", str(ws / "log"),
        "build", "--base-paths", str(REPO),
        "--build-base", str(ws / "build"), "--install-base", str(ws / "install"),
        "--event-handlers", "console_direct-",
    ]
    proc = subprocess.run(cmd, cwd=ws, env=_clean_env(COLCON_HOME=str(ws / "colcon_home")),
                          stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                          timeout=BUILD_TIMEOUT_S)
    assert proc.returncode == 0, f"colcon build failed:\n$ {shlex.join(cmd)}\n{proc.stdout}"
    # rheo_shaping alone: vendor/tf2_msgs (COLCON_IGNORE) is dev.py's, a workspace has its own
    assert "1 package finished" in proc.stdout, proc.stdout
    return ws


@pytest.fixture(scope="module")
def install(workspace) -> Path:
    return workspace / "install"


@pytest.fixture(scope="module")
def prefix(install) -> Path:
    """The package's prefix as ament_index finds it (what ``ros2 run`` uses)."""
    code = ("from ament_index_python.packages import get_package_prefix; "
            f"print(get_package_prefix({PACKAGE!r}))")
    out = subprocess.run([sys.executable, "-c", code], check=True, stdout=subprocess.PIPE,
                         text=True, env=_clean_env(AMENT_PREFIX_PATH=str(install / PACKAGE)))
    return Path(out.stdout.strip())


def test_ament_index_finds_the_isolated_prefix(install, prefix):
    assert prefix == install / PACKAGE
    marker = prefix / "share" / "ament_index" / "resource_index" / "packages" / PACKAGE
    assert marker.is_file()


@pytest.mark.parametrize("exe", EXECUTABLES)
def test_executable_installed_where_ros2_run_looks(prefix, exe):
    path = prefix / "lib" / PACKAGE / exe
    assert path.is_file(), f"missing {path}"
    assert os.access(path, os.X_OK), f"not executable: {path}"


def test_package_xml_and_config_installed(prefix):
    share = prefix / "share" / PACKAGE
    assert (share / "package.xml").read_bytes() == (REPO / "package.xml").read_bytes()
    wanted = sorted(p.name for p in (REPO / "config").glob("*.yaml"))
    installed = sorted(p.name for p in (share / "config").glob("*.yaml"))
    assert installed == wanted
    for name in wanted:
        assert (share / "config" / name).read_bytes() == (REPO / "config" / name).read_bytes()


def test_launch_and_rviz_files_installed(prefix):
    share = prefix / "share" / PACKAGE
    for rel in ("launch/cell.launch.py", "rviz/cell.rviz"):
        assert (share / rel).read_bytes() == (REPO / rel).read_bytes(), rel


def test_packaged_data_installed(prefix):
    data_src = REPO / PACKAGE / "data"
    wanted = sorted(p.name for p in data_src.glob("*") if p.is_file()) if data_src.is_dir() else []
    site = next(prefix.glob(f"lib/python3*/site-packages/{PACKAGE}"))
    installed = sorted(p.name for p in (site / "data").glob("*") if p.is_file())
    assert installed == wanted


def _sourced(install: Path, command: str) -> list[str]:
    """``command`` run as after ``source <install>/setup.bash``."""
    return ["bash", "-c", f"source {shlex.quote(str(install / 'setup.bash'))} && exec {command}"]


def test_cli_help_from_lib(install, prefix):
    exe = prefix / "lib" / PACKAGE / "rheo-shaping"
    proc = subprocess.run(_sourced(install, f"{shlex.quote(str(exe))} --help"),
                          env=_clean_env(), stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                          text=True, timeout=60)
    assert proc.returncode == 0, proc.stdout
    assert "usage: rheo-shaping" in proc.stdout


def test_sourced_workspace_imports_the_installed_package(install, prefix):
    """After sourcing, Python imports rheo_shaping from the install, not the source tree."""
    code = "import rheo_shaping; print(rheo_shaping.__file__)"
    proc = subprocess.run(_sourced(install, f"{shlex.quote(sys.executable)} -c "
                                            f"{shlex.quote(code)}"),
                          env=_clean_env(), stdout=subprocess.PIPE, text=True, timeout=60,
                          cwd=install)
    assert proc.returncode == 0
    assert Path(proc.stdout.strip()).is_relative_to(prefix), proc.stdout


@pytest.fixture(scope="module")
def node_domain(claim_ros_domain) -> int:
    """A ROS_DOMAIN_ID of its own for the start/stop tests.

    Earlier ROS tests of the session SIGKILL node processes named ``planner`` and
    ``simulator`` (test/nodes/test_faults.py). DDS keeps such a participant in the
    graph until its lease runs out (20 s with Fast DDS), and a ghost ``planner``
    would let the test signal the new process before it has even started rclpy.
    A fresh domain holds only the nodes started here.
    """
    return claim_ros_domain()


@pytest.fixture(scope="module")
def observer(node_domain):
    """An rclpy node in its own context (and domain) that watches the ROS graph."""
    import rclpy
    from rclpy.context import Context

    context = Context()
    rclpy.init(context=context, domain_id=node_domain)
    node = rclpy.create_node("colcon_layout_test_observer", context=context)
    try:
        yield node
    finally:
        node.destroy_node()
        rclpy.try_shutdown(context=context)


def _wait_for_node(observer, name: str, proc: subprocess.Popen, timeout: float,
                   log: Path | None = None) -> bool:
    """Poll the graph until ``name`` appears (True), the process dies or time runs out; with
    ``log``, also until the node's logger has spoken there (a managed and a plain node share
    a name: the graph may still list the one that has just exited)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if name in observer.get_node_names() and (log is None
                                                  or f"[{name}]" in log.read_text()):
            return True
        if proc.poll() is not None:
            return False
        time.sleep(0.1)
    return False


@pytest.mark.parametrize("exe_name, node_name",
                         [(n, n) for n in NODES] + list(MANAGED.items()))
def test_node_starts_and_stops_on_sigint(install, prefix, observer, node_domain, exe_name,
                                         node_name, tmp_path):
    exe = prefix / "lib" / PACKAGE / exe_name
    log = tmp_path / f"{exe_name}.log"
    with open(log, "w") as out:
        proc = subprocess.Popen(
            _sourced(install,
                     shlex.quote(str(exe))), env=_clean_env(ROS_DOMAIN_ID=str(node_domain)),
            stdin=subprocess.DEVNULL, stdout=out, stderr=subprocess.STDOUT,
            start_new_session=True,  # a Ctrl-C on the test run does not hit it
            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
        )
        try:
            seen = _wait_for_node(observer, node_name, proc, START_TIMEOUT_S, log)
            assert seen, (f"node {node_name!r} not in the ROS graph within {START_TIMEOUT_S} s "
                          f"(exit code {proc.poll()}); its output:\n{log.read_text()}")
            proc.send_signal(signal.SIGINT)  # bash exec'd the node: this pid is the node
            try:
                rc = proc.wait(timeout=STOP_TIMEOUT_S)
            except subprocess.TimeoutExpired:
                pytest.fail(f"{node_name} did not exit within {STOP_TIMEOUT_S} s of SIGINT; "
                            f"its output:\n{log.read_text()}")
            assert rc == 0, (f"{node_name} exited with {rc} on SIGINT; its output:\n"
                             f"{log.read_text()}")
        finally:
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait()
    assert f"[{node_name}]" in log.read_text()  # its logger spoke


# -- colcon test ------------------------------------------------------------------------
#: A small, fast subset of the ROS-free tests for colcon test (a bare `colcon test`
#: runs setup.cfg's testpaths, all of test/core).
COLCON_TEST_SUBSET = ("test/params/test_params_file_rule.py",
                      "test/package/test_package_manifest.py",
                      "test/package/test_launch_files.py")


def _colcon_test(workspace: Path, results: str,
                 pytest_args: list[str]) -> subprocess.CompletedProcess:
    cmd = [*_colcon_cmd(), "--log-base", str(workspace / "log"), "test",
           "--base-paths", str(REPO), "--build-base", str(workspace / "build"),
           "--install-base", str(workspace / "install"),
           "--test-result-base", str(workspace / results), "--return-code-on-test-failure",
           "--event-handlers", "console_direct-", "--pytest-args", *pytest_args]
    return subprocess.run(cmd, cwd=workspace,
                          env=_clean_env(COLCON_HOME=str(workspace / "colcon_home")),
                          stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                          timeout=BUILD_TIMEOUT_S)


def _test_result(workspace: Path, results: str) -> tuple[int, str]:
    # in the workspace, its log there too: colcon writes log/ into its working directory,
    # which is the package's source folder when `colcon test` runs this test
    proc = subprocess.run([*_colcon_cmd(), "--log-base", str(workspace / "log"), "test-result",
                           "--test-result-base", str(workspace / results)], cwd=workspace,
                          stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                          timeout=60, env=_clean_env(COLCON_HOME=str(workspace / "colcon_home")))
    return proc.returncode, proc.stdout


def test_colcon_test_runs_the_package_pytest_tests(workspace):
    """colcon picks pytest (setup.py's tests_require) and the tests run and pass."""
    import re
    proc = _colcon_test(workspace, "results", list(COLCON_TEST_SUBSET))
    assert proc.returncode == 0, proc.stdout
    rc, text = _test_result(workspace, "results")
    summary = re.search(
        r"Summary: (\d+) tests?, (\d+) errors?, (\d+) failures?, (\d+) skipped", text)
    assert summary, text
    tests, errors, failures, _skipped = map(int, summary.groups())
    print(f"colcon test: {tests} tests, {errors} errors, {failures} failures")
    assert rc == 0 and tests > 0 and errors == 0 and failures == 0, text
    assert (workspace / "results" / PACKAGE / "pytest.xml").is_file()


def test_colcon_test_fails_when_a_test_fails(workspace, tmp_path):
    failing = tmp_path / "test_must_fail.py"
    failing.write_text("def test_fails():\n    assert 1 == 2\n")
    proc = _colcon_test(workspace, "results_failing", [str(failing)])
    assert proc.returncode != 0, proc.stdout
    rc, text = _test_result(workspace, "results_failing")
    assert rc != 0 and "1 failure" in text, text


# -- the source folder stays as it was -------------------------------------------------------
def _source_copy(dest: Path) -> Path:
    """The repository's files as they are now (tracked and untracked, not ignored) copied
    to ``dest`` and committed there, so that ``git status`` shows what a build adds."""
    import shutil
    files = subprocess.run(["git", "-C", str(REPO), "ls-files", "-z", "--cached", "--others",
                            "--exclude-standard"], check=True, stdout=subprocess.PIPE
                           ).stdout.decode().split("\0")
    for rel in filter(None, files):
        src = REPO / rel
        if src.is_file():
            (dest / rel).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, dest / rel)
    git = ["git", "-C", str(dest), "-c", "user.name=test", "-c", "user.email=test@invalid"]
    subprocess.run([*git, "init", "-q"], check=True)
    subprocess.run([*git, "add", "-A"], check=True)
    subprocess.run([*git, "commit", "-q", "-m", "copy"], check=True)
    return dest


@pytest.mark.parametrize("symlink", [False, True], ids=["install", "symlink-install"])
def test_colcon_build_writes_nothing_into_the_source_folder(tmp_path, symlink):
    """``git status --porcelain --ignored`` of the built copy is empty: no build/launchers,
    no egg-info, nothing git ignores either; and ``ros2 run``'s executables are there."""
    src = _source_copy(tmp_path / "src" / PACKAGE)
    ws = tmp_path / "ws"
    cmd = [*_colcon_cmd(), "--log-base", str(ws / "log"), "build", "--base-paths", str(src),
           "--build-base", str(ws / "build"), "--install-base", str(ws / "install"),
           "--event-handlers", "console_direct-", *(["--symlink-install"] if symlink else [])]
    ws.mkdir()
    proc = subprocess.run(cmd, cwd=ws, env=_clean_env(COLCON_HOME=str(ws / "colcon_home")),
                          stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                          timeout=BUILD_TIMEOUT_S)
    assert proc.returncode == 0, f"colcon build failed:\n{proc.stdout}"
    status = subprocess.run(["git", "-C", str(src), "status", "--porcelain", "--ignored"],
                            check=True, stdout=subprocess.PIPE, text=True).stdout
    assert status == "", f"colcon build wrote into the source folder:\n{status}"
    for exe in EXECUTABLES:
        path = ws / "install" / PACKAGE / "lib" / PACKAGE / exe
        assert path.is_file() and os.access(path, os.X_OK), path
    for node in (*NODES, *MANAGED):
        text = (ws / "install" / PACKAGE / "lib" / PACKAGE / node).read_text()
        assert text.startswith("#!/bin/sh\n") and f"entry import {node}\n" in text, node


def test_a_bare_pytest_where_rclpy_imports_collects_every_stage():
    """`colcon test` runs pytest without --stage: in a ROS 2 environment that is every test
    of both stages (node tests included), not the ROS-free ones only."""
    import subprocess as _sp
    import sys as _sys

    from _support.stages import stage_of
    ids = {}
    for stage in ("auto", "ros"):
        out = _sp.run([_sys.executable, "-m", "pytest", "--collect-only", "-q", "-p",
                       "no:cacheprovider", f"--stage={stage}", "test"], cwd=REPO,
                      capture_output=True, text=True).stdout
        ids[stage] = {line for line in out.splitlines() if "::" in line}
        assert ids[stage], out[-2000:]
    by_stage = {s: {i for i in ids["auto"] if stage_of(REPO / i.split("::")[0]) == s}
                for s in ("core", "ros")}
    assert by_stage["ros"] == ids["ros"]
    assert len(by_stage["core"]) > len(ids["ros"]) > 0
    assert by_stage["core"] | by_stage["ros"] == ids["auto"]
