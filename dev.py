#!/usr/bin/env python3
"""rheo_shaping developer entry point: set up, run, test (standard library only).

commands:
  setup [--noble]       create/refresh .venv and .venv-core, with --noble .venv-noble too
                        (skipped while the requirement files, setup.py and setup.cfg are
                        unchanged)
  run [ARGS...]         `rheo-shaping ARGS` in .venv; without ARGS the main job,
                        `rheo-shaping cell` (the ROS 2 cell on the default cell)
  test [PYTEST_ARGS...] the whole suite: the core stage in .venv-core (after checking that
                        rclpy is NOT importable there) and the ros stage in .venv, side by
                        side (each stage's output when it ends); a path argument goes only
                        to its stage
  test --serial [...]   the stages one after the other, output live
  test --noble [...]    the noble stage alone: the core tests in .venv-noble, on the versions
                        Ubuntu 24.04 ships for Jazzy (requirements-noble.txt)
  test --stages=LIST    the stages named (core,ros,noble); CI (.ci/run) runs all three

Only what venv + pip + pytest do not do themselves: three virtualenvs, refreshed when a
stamp of their inputs' hash changes (.venv: requirements-ros.txt with the ROS 2 Jazzy
wheels; .venv-core: requirements-core.txt, no ROS; .venv-noble: requirements-noble.txt,
the core pinned to Ubuntu 24.04's versions, made only for the noble stage; each then
`pip install -e .`); tf2_msgs' messages, which no wheel has, built from vendor/tf2_msgs
into .venv with the ament_cmake and rosidl wheels (cmake and a C++ compiler; about 20 s,
once: stamped like the venvs; skipped where tf2_msgs is importable already); the suite
split between them by test/_support/stages.py; a ROS_DOMAIN_ID of this run's own and
LOCALHOST discovery for every ROS process; the time of each stage at the end.
"""
from __future__ import annotations

import argparse
import concurrent.futures
import contextlib
import fcntl
import hashlib
import os
import shlex
import subprocess
import sys
import tempfile
import time
import xml.etree.ElementTree as ET
from pathlib import Path

ROOT = Path(__file__).resolve().parent
MAIN_JOB = ["cell"]        # `dev.py run` without arguments: the ROS 2 shaping cell
VENV_PYTHON = (3, 11)      # the ROS 2 Jazzy wheels on PyPI are built for CPython 3.11

sys.path.insert(0, str(ROOT / "test"))
from _support.domains import claim_domain_id  # noqa: E402  (test/_support: stdlib only)
from _support.stages import STAGES, folders, stage_of  # noqa: E402


def say(msg: str) -> None:
    print(f"[dev] {msg}", flush=True)


def run_checked(cmd: list) -> None:
    """Run ``cmd``, exit if it fails; drop pip's warnings about this machine's local index
    folders that lack a package (one line per package, noise)."""
    say("$ " + " ".join(shlex.quote(str(c)) for c in cmd))
    proc = subprocess.Popen([str(c) for c in cmd], stderr=subprocess.PIPE, text=True,
                            errors="replace", bufsize=1)
    for line in proc.stderr:
        if not (line.startswith("WARNING: Location '") and "is ignored" in line):
            sys.stderr.write(line)
    rc = proc.wait()
    if rc != 0:
        raise SystemExit(f"[dev] command failed with exit code {rc}: {cmd[0]} ...")


def base_python() -> str:
    """Python 3.11, this interpreter or one on PATH."""
    if sys.version_info[:2] == VENV_PYTHON:
        return sys.executable
    import shutil
    name = "python%d.%d" % VENV_PYTHON
    found = shutil.which(name)
    if not found:
        raise SystemExit(f"[dev] the virtualenvs need {name} (the ROS 2 Jazzy wheels are "
                         f"built for it); this is Python {sys.version.split()[0]} and no "
                         f"{name} is on PATH")
    return found


def included(name: str, seen: tuple[str, ...] = ()) -> list[str]:
    """``name`` and the requirement files it includes (``-r FILE``), recursively, as paths
    relative to the checkout."""
    if name in seen:
        return []
    out, path = [name], ROOT / name
    for line in path.read_text().splitlines() if path.exists() else []:
        words = line.split("#", 1)[0].split()
        if len(words) == 2 and words[0] in ("-r", "--requirement"):
            ref = (path.parent / words[1]).resolve().relative_to(ROOT).as_posix()
            out += included(ref, (*seen, name))
    return out


class Venv:
    """One of the project's virtualenvs, stamped with the hash of what it was built from."""

    def __init__(self, name: str, requirements: str):
        self.path, self.requirements = ROOT / name, requirements
        self.inputs = included(requirements) + ["setup.py", "setup.cfg"]
        self.python = self.path / "bin" / "python"
        self.stamp = self.path / ".rheo_shaping-stamp"

    def wanted(self) -> str:
        h = hashlib.sha256()
        for name in self.inputs:
            path = ROOT / name
            h.update(name.encode() + (path.read_bytes() if path.exists() else b"<missing>"))
        return h.hexdigest()

    def current(self) -> bool:
        return (self.python.exists() and self.stamp.exists()
                and self.stamp.read_text().strip() == self.wanted())

    def ensure(self, verbose: bool) -> None:
        t0 = time.monotonic()
        if not self.python.exists() or subprocess.run([str(self.python), "-c", ""],
                                                      capture_output=True).returncode:
            say(f"{self.path.name}: creating the virtualenv")
            run_checked([base_python(), "-m", "venv", "--clear", self.path])
        self.stamp.unlink(missing_ok=True)
        pip = [self.python, "-m", "pip", "install", "--progress-bar", "off",
               "--disable-pip-version-check", *([] if verbose else ["--quiet"])]
        say(f"{self.path.name}: pip install (this can take a few minutes)")
        run_checked([*pip, "-r", ROOT / self.requirements])
        run_checked([*pip, "-e", ROOT])
        self.stamp.write_text(self.wanted() + "\n")
        say(f"{self.path.name}: ready in {time.monotonic() - t0:.0f} s")


FULL = Venv(".venv", "requirements-ros.txt")
CORE = Venv(".venv-core", "requirements-core.txt")
# the core on the numpy/scipy/matplotlib/numba/PyYAML that Ubuntu 24.04 ships for Jazzy,
# under VENV_PYTHON (noble's own python3 is 3.12; the nearest test the wheels allow)
NOBLE = Venv(".venv-noble", "requirements-noble.txt")

# stage -> (its virtualenv, the test folders' stage in test/_support/stages.py)
STAGE_VENVS = {"core": (CORE, "core"), "ros": (FULL, "ros"), "noble": (NOBLE, "core")}
DEFAULT_STAGES = ("core", "ros")   # `dev.py test`; the README's command, under 10 minutes


#: tf2_msgs' message files (ros2/geometry2, jazzy) and the ament_cmake package that builds
#: them (COLCON_IGNORE: a colcon workspace never builds it; a ROS installation has tf2_msgs).
TF2_MSGS = ROOT / "vendor" / "tf2_msgs"


def ensure_tf2_msgs(venv: Venv) -> None:
    """Build tf2_msgs (TFMessage, TF2Error) into ``venv`` unless it imports there already:
    cmake on vendor/tf2_msgs with the venv's ament_cmake and rosidl wheels, installed into
    the venv's prefix (its Python package into site-packages, its libraries into lib/, on
    the wheels' LD_LIBRARY_PATH). Stamped with the hash of the vendored files and the venv's
    own stamp; the build folder stays in the venv (a rebuild of the venv removes it)."""
    stamp = venv.path / ".tf2_msgs-stamp"
    h = hashlib.sha256(venv.stamp.read_bytes())
    for path in sorted(p for p in TF2_MSGS.rglob("*") if p.is_file()):
        h.update(path.relative_to(ROOT).as_posix().encode() + path.read_bytes())
    if stamp.exists() and stamp.read_text().strip() == h.hexdigest():
        say(f"{venv.path.name}: tf2_msgs up to date")
        return
    stamp.unlink(missing_ok=True)
    ours = venv.path / "share" / "tf2_msgs" / "rheo_vendored"    # our build's mark
    probe = subprocess.run([str(venv.python), "-c", "import tf2_msgs.msg"],
                           env=dict(os.environ, PYTHONPATH=""), capture_output=True)
    if probe.returncode == 0 and not ours.exists():
        say(f"{venv.path.name}: tf2_msgs is installed (not built here)")
        stamp.write_text(h.hexdigest() + "\n")
        return
    t0 = time.monotonic()
    say(f"{venv.path.name}: building tf2_msgs' messages from {TF2_MSGS.relative_to(ROOT)}")
    build = venv.path / "build" / "tf2_msgs"
    prefix = str(venv.path)
    env = dict(os.environ, AMENT_PREFIX_PATH=prefix, CMAKE_PREFIX_PATH=prefix,
               PATH=f"{venv.path / 'bin'}{os.pathsep}{os.environ.get('PATH', '')}")
    env.pop("PYTHONPATH", None)
    for cmd in (["cmake", "-S", TF2_MSGS, "-B", build, f"-DCMAKE_INSTALL_PREFIX={prefix}",
                 f"-DPython3_EXECUTABLE={venv.python}", "-DCMAKE_BUILD_TYPE=Release",
                 "-DBUILD_TESTING=OFF"],
                ["cmake", "--build", build, "-j", str(os.cpu_count() or 1)],
                ["cmake", "--install", build]):
        try:
            proc = subprocess.run([str(c) for c in cmd], env=env, stdout=subprocess.PIPE,
                                  stderr=subprocess.STDOUT, text=True, errors="replace")
        except OSError as exc:
            raise SystemExit(f"[dev] building tf2_msgs needs cmake and a C++ compiler: {exc}")
        if proc.returncode != 0:
            sys.stderr.write(proc.stdout[-6000:])
            raise SystemExit(f"[dev] building tf2_msgs failed ({cmd[0]} {cmd[1]} ..., exit "
                             f"code {proc.returncode}; its output above; "
                             f"vendor/tf2_msgs/README.md says what it builds)")
    ours.write_text(
        "built by rheo_shaping's dev.py from vendor/tf2_msgs\n")
    probe = subprocess.run([str(venv.python), "-c", "from tf2_msgs.msg import TFMessage"],
                           env=dict(os.environ, PYTHONPATH=""), capture_output=True, text=True)
    if probe.returncode != 0:
        raise SystemExit(f"[dev] tf2_msgs was built but does not import: "
                         f"{probe.stderr.strip()[-2000:]}")
    stamp.write_text(h.hexdigest() + "\n")
    say(f"{venv.path.name}: tf2_msgs built in {time.monotonic() - t0:.0f} s")


def ensure_venvs(venvs: list[Venv], verbose: bool) -> None:
    """Set up the venvs that need it, side by side (pip mostly waits on downloads and
    unpacking: two at once take about 60 % of the time of one after the other), under a
    lock that serialises concurrent dev.py runs on this checkout."""
    key = hashlib.sha256(str(ROOT).encode()).hexdigest()[:12]
    with open(Path(tempfile.gettempdir()) / f"rheo_shaping-setup-{key}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        todo = [v for v in venvs if not v.current()]
        for v in venvs:
            if v not in todo:
                say(f"{v.path.name}: up to date")
        with concurrent.futures.ThreadPoolExecutor(max(1, len(todo))) as pool:
            for future in [pool.submit(v.ensure, verbose) for v in todo]:
                future.result()                    # a failed set-up exits here
        if FULL in venvs:
            ensure_tf2_msgs(FULL)


def ros_env() -> dict[str, str]:
    """The environment of ROS processes: local-only discovery, a domain of our own."""
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    env.pop("_ROS_WHEELS_BOOTSTRAP_COMPLETE", None)  # let the venv's ROS wheels bootstrap
    if not env.get("ROS_DOMAIN_ID"):
        env["ROS_DOMAIN_ID"] = str(claim_domain_id())
    return env


def cmd_setup(args: list[str], verbose: bool) -> int:
    if args not in ([], ["--noble"]):
        raise SystemExit("usage: python3 dev.py setup [--noble]   (--noble: .venv-noble too)")
    ensure_venvs([CORE, FULL, *([NOBLE] if args else [])], verbose)
    say("done: .venv/bin/rheo-shaping --help")
    return 0


def cmd_run(args: list[str], verbose: bool) -> int:
    ensure_venvs([FULL], verbose)
    env, cmd = ros_env(), [str(FULL.path / "bin" / "rheo-shaping"), *(args or MAIN_JOB)]
    say(f"ROS_DOMAIN_ID={env['ROS_DOMAIN_ID']} $ " + " ".join(shlex.quote(c) for c in cmd))
    return subprocess.run(cmd, env=env).returncode


def split_pytest_args(args: list[str]) -> tuple[list[str], dict[str, list[str]]]:
    """(options for every stage, {stage: paths}): an argument naming an existing file or
    folder (with an optional ``::node``) goes to its stage (test/ itself to both)."""
    opts, paths = [], {stage: [] for stage in STAGES}
    for arg in args:
        head = arg.split("::", 1)[0]
        if arg.startswith("-") or not Path(head).exists():
            opts.append(arg)
            continue
        stage = stage_of(head)
        for st in (STAGES if stage is None else (stage,)):
            paths[st].append(str(Path(head).resolve()) + arg[len(head):])
    return opts, paths


def junit_counts(xml: Path) -> dict[str, int]:
    """passed/failed/skipped of a pytest --junitxml report (empty if it is missing)."""
    try:
        suite = ET.parse(xml).getroot().find("testsuite")
    except (OSError, ET.ParseError):
        return {}
    n = {k: int(suite.get(k, 0)) for k in ("tests", "failures", "errors", "skipped")}
    return {"passed": n["tests"] - n["failures"] - n["errors"] - n["skipped"],
            "failed": n["failures"] + n["errors"], "skipped": n["skipped"]}


def pick_stages(args: list[str]) -> tuple[list[str], list[str]]:
    """(the stages to run, the remaining arguments for pytest): ``--noble`` is the noble
    stage alone, ``--stages=core,ros,noble`` any of them; neither, :data:`DEFAULT_STAGES`."""
    stages, rest = None, []
    for arg in args:
        if arg == "--noble":
            stages = ["noble"]
        elif arg.startswith("--stages="):
            stages = [s for s in arg.split("=", 1)[1].split(",") if s]
            unknown = [s for s in stages if s not in STAGE_VENVS]
            if unknown or not stages:
                raise SystemExit(f"[dev] --stages takes {','.join(STAGE_VENVS)}, not "
                                 f"{arg.split('=', 1)[1]!r}")
        else:
            rest.append(arg)
    return [s for s in STAGE_VENVS if s in (stages or DEFAULT_STAGES)], rest


#: Stages that run side by side (``dev.py test --serial``: one after the other): all three
#: at once. The core and noble stages each keep about one core busy with numerics while the
#: ros stage mostly waits on DDS and on simulated time, so on two cores the three take about
#: the time of the longest (the ros stage); run one after another the noble stage added
#: its whole time to CI's.
STAGE_JOBS = 3

#: The noble stage leaves out the tests marked ``heavy`` (the benchmark worlds' and the
#: diagnosis's long searches): they run in the core stage; the noble stage checks the
#: core on noble's versions with the rest (docs/development.md).
NOBLE_MARKS = "not heavy"


def run_stage(stage: str, env: dict, opts: list[str], paths: dict, live: bool,
              logdir: Path) -> tuple[bool, dict, float]:
    """Run one stage's pytest (output live, or into ``logdir/<stage>.log`` and printed when
    it ends); (ok, counts, seconds)."""
    venv, tests = STAGE_VENVS[stage]
    t0 = time.monotonic()
    if stage == "noble" and "-m" not in opts:
        opts = [*opts, "-m", NOBLE_MARKS]
    if tests == "core" and subprocess.run([str(venv.python), "-c", "import rclpy"],
                                          env=env, capture_output=True).returncode == 0:
        say(f"{stage}: FAIL (`import rclpy` succeeds in {venv.path.name}: it must not)")
        return False, {"failed": 1}, 0.0
    xml = logdir / f"{stage}.xml"
    cmd = [str(venv.python), "-m", "pytest", f"--stage={tests}", f"--junitxml={xml}",
           *opts, *(paths[tests] or [str(d) for d in folders(tests)])]
    say(f"{stage}: ROS_DOMAIN_ID={env['ROS_DOMAIN_ID']} $ "
        + " ".join(shlex.quote(c) for c in cmd))
    if live:
        rc = subprocess.run(cmd, cwd=ROOT, env=env).returncode
    else:
        log = logdir / f"{stage}.log"
        say(f"{stage}: its output follows when it ends (meanwhile: tail -f {log})")
        with open(log, "w") as out:
            rc = subprocess.run(cmd, cwd=ROOT, env=env, stdout=out,
                                stderr=subprocess.STDOUT).returncode
        say(f"{stage}: output ({time.monotonic() - t0:.0f} s)")
        sys.stdout.write(log.read_text(errors="replace"))
        sys.stdout.flush()
    counts = junit_counts(xml)
    ok = rc in (0, 5)                         # 5: nothing collected, not a failure
    if not ok and not counts.get("failed"):
        counts["failed"] = 1                  # pytest itself failed (usage error, crash)
    return ok, counts, time.monotonic() - t0


def cmd_test(args: list[str], verbose: bool) -> int:
    t_all = time.monotonic()
    serial = "--serial" in args
    args = [a for a in args if a != "--serial"]
    stages, args = pick_stages(args)
    ensure_venvs([STAGE_VENVS[s][0] for s in stages], verbose)
    env, (opts, paths) = ros_env(), split_pytest_args(args)
    lines = [f"setup: ok ({time.monotonic() - t_all:.0f} s)"]
    totals, failed = {"passed": 0, "failed": 0, "skipped": 0}, []
    todo = [s for s in stages if not (any(paths.values()) and not paths[STAGE_VENVS[s][1]])]
    jobs = 1 if serial or len(todo) < 2 else STAGE_JOBS
    if jobs > 1:
        say(f"test: stages {', '.join(todo)}, {jobs} at a time (--serial: one after the other)")
    with tempfile.TemporaryDirectory() as tmp, \
            concurrent.futures.ThreadPoolExecutor(jobs) as pool:
        futures = {s: pool.submit(run_stage, s, env, opts, paths, jobs == 1, Path(tmp))
                   for s in todo}
        for stage in todo:                    # the summary in stage order
            ok, counts, seconds = futures[stage].result()
            for k in totals:
                totals[k] += counts.get(k, 0)
            failed += [] if ok else [stage]
            lines.append(f"{stage}: {'ok' if ok else 'FAIL'} ({counts.get('passed', 0)} "
                         f"passed, {counts.get('failed', 0)} failed, "
                         f"{counts.get('skipped', 0)} skipped; {seconds:.0f} s)")
    print()
    for line in lines:
        say("test " + line)
    say(f"test: {'FAILED: ' + ', '.join(failed) if failed else 'all stages passed'} in "
        f"{time.monotonic() - t_all:.0f} s")
    # the closing line, in the plain form CI reads
    print(f"tests: {totals['passed']} passed, {totals['failed']} failed, "
          f"{totals['skipped']} skipped", flush=True)
    return 1 if failed else 0


COMMANDS = {"setup": cmd_setup, "run": cmd_run, "test": cmd_test}


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = argparse.ArgumentParser(
        prog="python3 dev.py", formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Set up, run and test rheo_shaping (needs only Python 3.11 and PyPI).",
        epilog=__doc__.split("\n\n", 1)[1])
    parser.add_argument("-v", "--verbose", action="store_true",
                        help="show pip's output while setting up")
    parser.add_argument("command", choices=sorted(COMMANDS), metavar="COMMAND",
                        help="setup | run | test (see below)")
    # options before the command belong to dev.py; everything after it to the command
    split = next((i for i, a in enumerate(argv) if not a.startswith("-")), len(argv))
    ns = parser.parse_args(argv[:split + 1])
    with contextlib.suppress(KeyboardInterrupt):
        return COMMANDS[ns.command](argv[split + 1:], ns.verbose)
    print("[dev] interrupted", file=sys.stderr)
    return 130


if __name__ == "__main__":
    sys.exit(main())
