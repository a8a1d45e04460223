"""`colcon test` of the committed tree against the suite's own stages (issue 28).

A user of a Jazzy workspace runs ``colcon build`` then ``colcon test --packages-select
rheo_shaping`` and ``colcon test-result --verbose``.  This script does exactly that in a
temporary workspace on a clone of the committed tree (``git clone``, HEAD), then collects
the suite's core and ros stages on the same copy (``pytest --collect-only --stage=core`` in
``.venv-core``, ``--stage=ros`` in ``.venv``, as ``python3 dev.py test`` splits them) and
compares test by test: the tests colcon ran that the stages do not collect, and the other
way round.  It prints colcon's summary (tests, errors, failures, skipped), the two stages'
counts and the differences; ``--json`` prints one object.  Exit code 0 when the two sets
are equal and colcon reports no error and no failure, 1 otherwise.

    python3 benchmarks/colcon_test_count.py            # the whole package: ~10-20 min
    python3 benchmarks/colcon_test_count.py --json --keep

It needs the worktree's ``.venv`` (colcon, rclpy) and ``.venv-core`` (``python3 dev.py
setup``).  The noble stage runs the core tests again in other library versions; it adds no
test of its own, so it is not counted.
"""
from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
import xml.etree.ElementTree as ET
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
PACKAGE = "rheo_shaping"
SUMMARY = re.compile(r"Summary: (\d+) tests?, (\d+) errors?, (\d+) failures?, (\d+) skipped")


def _env(**extra: str) -> dict[str, str]:
    """This environment without a sourced ROS workspace (as test_colcon_layout.py)."""
    env = dict(os.environ)
    for var in ("AMENT_PREFIX_PATH", "COLCON_PREFIX_PATH", "CMAKE_PREFIX_PATH", "PYTHONPATH"):
        env.pop(var, None)
    env.update(extra)
    return env


def _run(cmd: list[str], cwd: Path, env: dict, timeout: float) -> subprocess.CompletedProcess:
    return subprocess.run(cmd, cwd=cwd, env=env, stdout=subprocess.PIPE,
                          stderr=subprocess.STDOUT, text=True, timeout=timeout)


def copy_committed_tree(dest: Path) -> str:
    """A clone of the repository's committed HEAD in ``dest`` (as a user checks it out into a
    workspace's ``src``: a git checkout, which test_colcon_layout.py copies from); returns
    the commit."""
    commit = subprocess.run(["git", "-C", str(REPO), "rev-parse", "HEAD"], check=True,
                            stdout=subprocess.PIPE, text=True).stdout.strip()
    subprocess.run(["git", "clone", "--quiet", "--no-checkout", str(REPO), str(dest)],
                   check=True)
    subprocess.run(["git", "-C", str(dest), "checkout", "--quiet", commit], check=True)
    return commit


def junit_ids(xml: Path, prefix: str = "") -> list[str]:
    """``module.path.[Class.]test[param]`` of every test case of a JUnit report (a
    ``--junit-prefix`` dropped)."""
    out = []
    for case in ET.parse(xml).getroot().iter("testcase"):
        cls = case.get("classname", "")
        if prefix and cls.startswith(prefix + "."):
            cls = cls[len(prefix) + 1:]
        out.append(f"{cls}.{case.get('name')}")
    return out


def nodeid_key(nodeid: str) -> str:
    """A pytest node id (``test/a/test_b.py::TestC::test_d[x/y]``) as JUnit names it."""
    path, _, rest = nodeid.partition("::")
    return path[:-3].replace("/", ".") + "." + rest.replace("::", ".")


def collect(python: Path, stage: str, src: Path, timeout: float) -> list[str]:
    """The node ids ``pytest --collect-only --stage=STAGE`` collects in ``src``."""
    proc = _run([str(python), "-m", "pytest", "--collect-only", "-q", "-p", "no:cacheprovider",
                 f"--stage={stage}"], src, _env(), timeout)
    ids = [line.strip() for line in proc.stdout.splitlines() if "::" in line]
    if proc.returncode != 0 or not ids:
        raise SystemExit(f"pytest --collect-only --stage={stage} failed:\n{proc.stdout[-3000:]}")
    return ids


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    ap.add_argument("--keep", action="store_true", help="keep the temporary workspace")
    ap.add_argument("--timeout", type=float, default=3600.0,
                    help="seconds each of build and test may take (default 3600)")
    args = ap.parse_args(argv)
    ros_py, core_py = REPO / ".venv" / "bin" / "python", REPO / ".venv-core" / "bin" / "python"
    colcon = REPO / ".venv" / "bin" / "colcon"
    for path in (ros_py, core_py, colcon):
        if not path.exists():
            raise SystemExit(f"{path} is missing: run python3 dev.py setup first")
    ws = Path(tempfile.mkdtemp(prefix="colcon_count_"))
    say = (lambda *a: None) if args.json else (lambda *a: print(*a, flush=True))
    out: dict = {"workspace": str(ws)}
    try:
        src = ws / "src" / PACKAGE
        out["commit"] = copy_committed_tree(src)
        env = _env(COLCON_HOME=str(ws / "colcon_home"))
        base = [str(ros_py), str(colcon), "--log-base", str(ws / "log")]
        paths = ["--base-paths", str(ws / "src"), "--build-base", str(ws / "build"),
                 "--install-base", str(ws / "install")]
        t0 = time.monotonic()
        say(f"colcon build of {out['commit'][:10]} in {ws} ...")
        build = _run([*base, "build", *paths, "--event-handlers", "console_direct-"], ws, env,
                     args.timeout)
        if build.returncode != 0:
            raise SystemExit(f"colcon build failed:\n{build.stdout[-3000:]}")
        out["build_s"] = round(time.monotonic() - t0, 1)
        say(f"colcon test --packages-select {PACKAGE} ...")
        t0 = time.monotonic()
        results = ws / "test_results"
        test = _run([*base, "test", *paths, "--packages-select", PACKAGE, "--test-result-base",
                     str(results), "--event-handlers", "console_direct-"], ws, env,
                    args.timeout)
        out["test_s"] = round(time.monotonic() - t0, 1)
        verdict = _run([str(ros_py), str(colcon), "test-result", "--verbose",
                        "--test-result-base", str(results)], ws, _env(), 600)
        found = SUMMARY.search(verdict.stdout)
        if not found:
            raise SystemExit(f"no summary from colcon test-result:\n{verdict.stdout[-3000:]}\n"
                             f"colcon test said:\n{test.stdout[-3000:]}")
        tests, errors, failures, skipped = map(int, found.groups())
        out["colcon"] = {"tests": tests, "errors": errors, "failures": failures,
                         "skipped": skipped, "test_result_rc": verdict.returncode}
        if errors or failures:
            out["colcon"]["verbose"] = verdict.stdout[-6000:]
        ran = junit_ids(results / PACKAGE / "pytest.xml", PACKAGE)
        say("collecting the suite's stages on the same tree ...")
        stages = {"core": collect(core_py, "core", src, 1200),
                  "ros": collect(ros_py, "ros", src, 1200)}
        out["stages"] = {k: len(v) for k, v in stages.items()}
        suite = {nodeid_key(i) for ids in stages.values() for i in ids}
        out["only_colcon"] = sorted(set(ran) - suite)
        out["only_suite"] = sorted(suite - set(ran))
        out["duplicates_colcon"] = len(ran) - len(set(ran))
        out["equal"] = (not out["only_colcon"] and not out["only_suite"]
                        and len(ran) == sum(out["stages"].values()) == tests)
    finally:
        if not args.keep:
            shutil.rmtree(ws, ignore_errors=True)
    ok = out["equal"] and not out["colcon"]["errors"] and not out["colcon"]["failures"]
    if args.json:
        print(json.dumps(out, indent=1))
    else:
        c = out["colcon"]
        print(f"colcon test ({out['commit'][:10]}): {c['tests']} tests, {c['errors']} errors, "
              f"{c['failures']} failures, {c['skipped']} skipped; build {out['build_s']} s, "
              f"test {out['test_s']} s")
        print(f"suite stages on the same tree: core {out['stages']['core']} + ros "
              f"{out['stages']['ros']} = {sum(out['stages'].values())}")
        for key in ("only_colcon", "only_suite"):
            print(f"{key}: {len(out[key])}" + "".join(f"\n  {i}" for i in out[key][:50]))
        if c.get("verbose"):
            print(c["verbose"])
        print("equal, 0 failures" if ok else "NOT equal or failures")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
