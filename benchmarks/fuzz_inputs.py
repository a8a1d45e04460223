#!/usr/bin/env python3
"""Fuzzing of what users hand the program: params files and recorded runs.

Params files: random mutations of ``config/cell.yaml`` (a leaf's type or value
changed to a string, list, bool, null, NaN, infinity, a huge, zero or negative
number; keys deleted or added; the ``ros__parameters`` level dropped; YAML
syntax broken by inserted, deleted or swapped characters and truncation; YAML
tags such as ``!!python/object/apply``) go into the core loader
(``rheo_shaping.params.config.load_cell``), a sample into ``rheo-shaping simulate
--params`` and, with ``--nodes N``, N of them into each node executable.

Records: a short valid record is written with ``rheo-shaping record``, then
mutated (the MCAP file truncated, bytes flipped, deleted, emptied; messages
with NaN and infinite values, out-of-order and duplicate stamps, empty and huge
topics, wrong message types; ``scenario.yaml`` mutated as above, YAML tags
included) and read with ``rheo_shaping.records.bag.read_record``; a sample goes
through ``rheo-shaping diagnose ... --out DIR``.

Pass: never a traceback (in-process: only ``ConfigError`` / ``RecordError``
or a valid result; in a subprocess: exit code 0 or 2 and no "Traceback" in its
output) and nothing written outside the output directory (the work folder is
listed before and after every command).

    .venv/bin/python benchmarks/fuzz_inputs.py [--params 2000] [--records 500]
        [--cli-every 20] [--nodes 0] [--seed 1] [--json]
"""
from __future__ import annotations

import argparse
import json
import math
import os
import random
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import yaml

REPO = Path(__file__).resolve().parents[1]
BIN = Path(sys.executable).parent
TAGS = ["!!python/object/apply:os.system ['touch {canary}']",
        "!!python/name:os.system", "!!binary aGVsbG8=", "!!set {{a, b}}",
        "&a [*a]", "!!python/tuple [1, 2]", "!custom 3"]
VALUES = ["'text'", "[1, 2]", "[1, 'a', true]", "true", "null", ".nan", ".inf", "-.inf",
          "1e308", "-1.0", "0", "0.0", "''", "{a: 1}", "1e-300", "18446744073709551617"]


# -- params files -------------------------------------------------------------------------
def _leaves(tree, path=()):
    if isinstance(tree, dict):
        for k, v in tree.items():
            yield from _leaves(v, path + (k,))
    else:
        yield path


def _set(tree, path, value):
    for k in path[:-1]:
        tree = tree[k]
    tree[path[-1]] = value


def _delete(tree, path):
    for k in path[:-1]:
        tree = tree[k]
    del tree[path[-1]]


def mutate_params(text: str, rng: random.Random, canary: Path) -> str:
    """One mutated params file (YAML text)."""
    kind = rng.choice(["value", "value", "delete", "extra", "unwrap", "syntax", "truncate",
                       "tag", "multi"])
    if kind in ("syntax", "truncate"):
        chars = list(text)
        if kind == "truncate":
            return text[:rng.randrange(len(text))]
        for _ in range(rng.randint(1, 5)):
            i = rng.randrange(len(chars))
            op = rng.choice(["insert", "delete", "swap"])
            if op == "insert":
                chars.insert(i, rng.choice(list(":{}[]-#&*!|>'\"\t %@`,?")))
            elif op == "delete":
                del chars[i]
            else:
                j = rng.randrange(len(chars))
                chars[i], chars[j] = chars[j], chars[i]
        return "".join(chars)
    data = yaml.safe_load(text)
    leaves = list(_leaves(data))
    if kind == "tag":
        path = rng.choice(leaves)
        lines = yaml.safe_dump(data, sort_keys=False).splitlines()
        key = f"{path[-1]}:"
        for i, line in enumerate(lines):
            if line.strip().startswith(key):
                lines[i] = line.split(":")[0] + ": " + rng.choice(TAGS).format(canary=canary)
                break
        return "\n".join(lines) + "\n"
    for _ in range(rng.randint(2, 4) if kind == "multi" else 1):
        path = rng.choice(leaves)
        op = kind if kind != "multi" else rng.choice(["value", "delete", "extra"])
        try:
            if op == "value":
                _set(data, path, yaml.safe_load(rng.choice(VALUES)))
            elif op == "delete":
                _delete(data, path)
                leaves = list(_leaves(data)) or [("x",)]
            elif op == "extra":
                _set(data,
                     path[:-1] + (rng.choice(["speed", "k", "n_masses2", "", "ros__parameters"]),),
                     rng.uniform(-1, 1))
            elif op == "unwrap":
                data = {k: v.get("ros__parameters", v) if isinstance(v, dict) else v
                        for k, v in data.items()}
        except (KeyError, TypeError):
            pass
    return yaml.safe_dump(data, sort_keys=False)


def check_load(path: Path) -> str:
    """'ok', 'refused' or the traceback-class failure."""
    from rheo_shaping.params.config import ConfigError, load_cell
    try:
        load_cell(path)
        return "ok"
    except ConfigError as exc:
        return "refused" if str(path.name) in str(exc) else f"refusal without the file: {exc}"
    except Exception as exc:  # noqa: BLE001 - this is what the fuzzer looks for
        return f"{type(exc).__name__}: {exc}"


def run_cli(args: list[str], cwd: Path, timeout: float = 300.0) -> str:
    """'ok' or 'refused' (exit 0 / 2, no traceback) or what went wrong."""
    try:
        p = subprocess.run(args, cwd=cwd, capture_output=True, text=True, timeout=timeout,
                           stdin=subprocess.DEVNULL)
    except subprocess.TimeoutExpired:
        return f"timeout after {timeout:g} s: {args[:3]}"
    out = p.stdout + p.stderr
    if "Traceback" in out:
        return f"traceback (exit {p.returncode}): {out[-600:]}"
    if p.returncode not in (0, 2):
        return f"exit {p.returncode}: {out[-300:]}"
    return "ok" if p.returncode == 0 else "refused"


def run_node(exe: str, params: Path, cwd: Path, settle: float = 3.0) -> str:
    """A node started on a fuzzed params file: refused (exit 2, no traceback) or it runs
    and then ends with exit 0 on SIGINT."""
    import signal
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    proc = subprocess.Popen([str(BIN / exe), "--ros-args", "--params-file", str(params)], cwd=cwd,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            stdin=subprocess.DEVNULL, env=env)
    try:
        out, _ = proc.communicate(timeout=settle)
    except subprocess.TimeoutExpired:
        proc.send_signal(signal.SIGINT)
        try:
            out, _ = proc.communicate(timeout=30.0)
        except subprocess.TimeoutExpired:
            proc.kill()
            return f"{exe}: no exit within 30 s of SIGINT"
    if "Traceback" in out:
        return f"{exe}: traceback (exit {proc.returncode}): {out[-600:]}"
    if proc.returncode not in (0, 2):
        return f"{exe}: exit {proc.returncode}: {out[-300:]}"
    return "ok" if proc.returncode == 0 else "refused"


def listing(root: Path, skip: Path | None = None) -> set[str]:
    out = set()
    for p in root.rglob("*"):
        if skip is not None and (p == skip or skip in p.parents):
            continue
        out.add(str(p.relative_to(root)))
    return out


# -- records --------------------------------------------------------------------------------
def base_record(work: Path, seconds: float) -> Path:
    """A short valid record from the simulator (``rheo-shaping record``)."""
    params = work / "short.yaml"
    text = (REPO / "config" / "cell.yaml").read_text()
    data = yaml.safe_load(text)
    data["/**"]["ros__parameters"]["movement"]["process_time"] = float(seconds)
    params.write_text(yaml.safe_dump(data))
    out = work / "base-record"
    res = subprocess.run([str(BIN / "rheo-shaping"), "record", "--params", str(params),
                          "--out", str(out), "--seed", "1"], capture_output=True, text=True)
    if res.returncode != 0:
        raise SystemExit(f"fuzz_inputs: could not write the base record: {res.stderr[-800:]}")
    return out


def mutate_record(base: Path, dest: Path, rng: random.Random, canary: Path) -> str:
    """A mutated copy of ``base`` at ``dest``; returns the kind of mutation."""
    shutil.copytree(base, dest)
    mcap = next(dest.glob("*.mcap"))
    kind = rng.choice(["truncate", "flip", "delete_bag", "empty_dir", "scenario", "scenario_tag",
                       "values", "stamps", "empty_topic", "huge_topic", "wrong_type", "metadata"])
    if kind == "truncate":
        data = mcap.read_bytes()
        mcap.write_bytes(data[:rng.randrange(len(data))])
    elif kind == "flip":
        data = bytearray(mcap.read_bytes())
        for _ in range(rng.randint(1, 20)):
            data[rng.randrange(len(data))] ^= 1 << rng.randrange(8)
        mcap.write_bytes(bytes(data))
    elif kind == "delete_bag":
        mcap.unlink()
    elif kind == "empty_dir":
        for p in dest.iterdir():
            p.unlink()
    elif kind == "metadata":
        meta = dest / "metadata.yaml"
        meta.write_text(mutate_params(meta.read_text(), rng, canary))
    elif kind in ("scenario", "scenario_tag"):
        sc = dest / "scenario.yaml"
        text = sc.read_text()
        sc.write_text(mutate_params(text, rng, canary) if kind == "scenario"
                      else text.replace("k1: 95.0",
                                        "k1: " + rng.choice(TAGS).format(canary=canary)))
    else:
        _rewrite_messages(base, dest, kind, rng)
    return kind


def _rewrite_messages(base: Path, dest: Path, kind: str, rng: random.Random) -> None:
    """Rewrite the bag with bad message contents (rosbags Writer, real MCAP)."""
    from rosbags.rosbag2 import Reader, StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore
    ts = get_typestore(Stores.ROS2_JAZZY)
    with Reader(base) as reader:
        items = [(c.topic, c.msgtype, t, raw) for c, t, raw in reader.messages()]
    for p in dest.iterdir():
        if p.name != "scenario.yaml":
            p.unlink()
    msgs = [(topic, mtype, t, ts.deserialize_cdr(raw, mtype)) for topic, mtype, t, raw in items]
    bad = [math.nan, math.inf, -math.inf, 1e308]
    if kind == "values":
        for _, _, _, msg in rng.sample(msgs, k=min(len(msgs), rng.randint(1, 5))):
            if hasattr(msg, "pose") and hasattr(msg.pose, "position"):
                msg.pose.position.x = rng.choice(bad)
            elif hasattr(msg, "poses") and msg.poses:
                rng.choice(msg.poses).position.z = rng.choice(bad)
            elif hasattr(msg, "wrench"):
                msg.wrench.force.x = rng.choice(bad)
    elif kind == "stamps":
        for _, _, _, msg in rng.sample(msgs, k=min(len(msgs), 20)):
            msg.header.stamp.sec = rng.choice([0, 1, msg.header.stamp.sec, 2 ** 31 - 1])
    elif kind == "empty_topic":
        drop = rng.choice(sorted({m[0] for m in msgs}))
        msgs = [m for m in msgs if m[0] != drop]
    elif kind == "huge_topic":
        extra = [m for m in msgs if m[0] == "/tool/pose"]
        msgs = msgs + extra * 20
    bag = dest.parent / (dest.name + "-bag")           # rosbags writes a new folder only
    with Writer(bag, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        conns = {}
        for topic, mtype, t, msg in msgs:
            out_type = mtype
            if kind == "wrong_type" and topic == "/tool/pose":
                out_type = "std_msgs/msg/String"
            if topic not in conns:
                conns[topic] = writer.add_connection(topic, out_type, typestore=ts)
            if out_type != mtype:
                data = ts.serialize_cdr(ts.types["std_msgs/msg/String"](data="x"), out_type)
            else:
                data = ts.serialize_cdr(msg, mtype)
            writer.write(conns[topic], t, data)
    for p in bag.iterdir():
        p.rename(dest / p.name)
    bag.rmdir()


def check_read(path: Path) -> str:
    from rheo_shaping.records.bag import RecordError, read_record
    try:
        read_record(path)
        return "ok"
    except RecordError as exc:
        return "refused" if path.name in str(exc) else f"refusal without the record: {exc}"
    except Exception as exc:  # noqa: BLE001
        return f"{type(exc).__name__}: {exc}"


# -- main -----------------------------------------------------------------------------------
def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--params", type=int, default=2000, help="fuzzed params files (default 2000)")
    ap.add_argument("--records", type=int, default=500, help="fuzzed records (default 500)")
    ap.add_argument("--cli-every", type=int, default=20, metavar="K",
                    help="every K-th input also goes through the command line (default 20)")
    ap.add_argument("--nodes", type=int, default=0, metavar="N",
                    help="start each node executable on N fuzzed params files (default 0)")
    ap.add_argument("--record-seconds", type=float, default=20.0,
                    help="process time of the base record [s] (default 20)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    args = ap.parse_args(argv)
    if min(args.params, args.records, args.cli_every) < 0 or args.cli_every == 0:
        print("fuzz_inputs: error: counts must be >= 0 and --cli-every >= 1", file=sys.stderr)
        return 2
    rng = random.Random(args.seed)
    failures: list[str] = []
    counts = {"params": {"ok": 0, "refused": 0}, "params_cli": {"ok": 0, "refused": 0},
              "nodes": {"ok": 0, "refused": 0}, "records": {"ok": 0, "refused": 0},
              "records_cli": {"ok": 0, "refused": 0}}
    t0 = time.monotonic()
    text = (REPO / "config" / "cell.yaml").read_text()
    with tempfile.TemporaryDirectory(prefix="rheo-fuzz-") as tmp:
        work = Path(tmp)
        canary = work / "canary-yaml-tag-ran"

        def tally(group: str, result: str, what: str) -> None:
            if result in ("ok", "refused"):
                counts[group][result] += 1
            else:
                failures.append(f"{group} {what}: {result}")

        for i in range(args.params):
            f = work / f"params-{i}.yaml"
            f.write_text(mutate_params(text, rng, canary))
            tally("params", check_load(f), f.name)
            if i % args.cli_every == 0:
                before = listing(work)
                tally("params_cli", run_cli([str(BIN / "rheo-shaping"), "simulate", "--params",
                                             str(f), "--json"], work), f.name)
                if listing(work) - before:
                    failures.append(f"simulate {f.name} wrote {sorted(listing(work) - before)}")
            if i < args.nodes:
                for exe in ("simulator", "planner", "monitor"):
                    if (BIN / exe).exists():
                        tally("nodes", run_node(exe, f, work), f"{exe} {f.name}")
            f.unlink()
        if args.records:
            base = base_record(work, args.record_seconds)
            for i in range(args.records):
                dest = work / f"rec-{i}"
                kind = mutate_record(base, dest, rng, canary)
                tally("records", check_read(dest), f"{dest.name} ({kind})")
                if i % args.cli_every == 0:
                    out = work / f"report-{i}"
                    before = listing(work)
                    tally("records_cli", run_cli([str(BIN / "rheo-shaping"), "diagnose", str(dest),
                                                  "--out", str(out), "--quiet"], work),
                          f"{dest.name} ({kind})")
                    new = {p for p in listing(work) - before
                           if not (p == out.name or p.startswith(out.name + "/"))}
                    if new:
                        failures.append(f"diagnose {dest.name} wrote outside --out: {sorted(new)}")
                    shutil.rmtree(out, ignore_errors=True)
                shutil.rmtree(dest)
        if canary.exists():
            failures.append("a YAML tag ran code (the canary file exists)")
    summary = {"counts": counts, "failures": len(failures), "first_failures": failures[:20],
               "wall_time_s": time.monotonic() - t0, "seed": args.seed}
    if args.json:
        print(json.dumps(summary))
    else:
        for group, c in counts.items():
            print(f"{group:12s} ok {c['ok']:5d}  refused {c['refused']:5d}")
        print(f"failures (tracebacks, writes outside --out): {len(failures)}")
        for f in failures[:20]:
            print("  " + f)
        print(f"{summary['wall_time_s']:.0f} s")
    return 0 if not failures else 1


if __name__ == "__main__":
    raise SystemExit(main())
