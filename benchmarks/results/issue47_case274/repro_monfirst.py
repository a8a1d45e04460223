import sys, os, json, time, math, re, signal, subprocess, tempfile, random, queue, concurrent.futures
from pathlib import Path
sys.path.insert(0, "/work/camp47/benchmarks")
import stress_campaign as sc
from stress_campaign import campaign, BIN, NUM, STOP
def run_case_logs(index: int, cell, prefix: list[str], domain: int,
                       timeout: float) -> dict:
    """Offline run, then the cell as three processes (inside ``prefix``); figures from logs."""
    import yaml

    from rheo_shaping.params.config import dump_cell

    row, offline = campaign.offline_case(index, cell)
    if offline is None:
        return row
    rtf = campaign.RTF
    with tempfile.TemporaryDirectory(prefix="rheo-stress-") as tmp:
        params = Path(tmp) / "cell.yaml"
        data = yaml.safe_load(dump_cell(cell))
        data["/**/simulator"] = {"ros__parameters": {
            "real_time_factor": rtf, "step_period": 0.2 / rtf, "publish_period": 0.0,
            "publish_markers": False, "camera": False}}
        data["/**/planner"] = {"ros__parameters": {"use_sim_time": True, "autostart": True}}
        data["/**/monitor"] = {"ros__parameters": {"use_sim_time": True}}
        params.write_text(yaml.safe_dump(data, sort_keys=False))
        env = dict(os.environ, ROS_DOMAIN_ID=str(domain),
                   ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST",
                   FASTDDS_BUILTIN_TRANSPORTS="UDPv4", RCUTILS_LOGGING_BUFFERED_STREAM="0")
        logs = {n: Path(tmp) / f"{n}.log" for n in ("simulator", "planner", "monitor")}
        procs = {}
        for n, log in logs.items():
            procs[n] = subprocess.Popen([*prefix, str(BIN / n), "--ros-args", "--params-file",
                                         str(params)], stdout=open(log, "w"),
                                        stderr=subprocess.STDOUT, env=env,
                                        stdin=subprocess.DEVNULL,
                                        start_new_session=True)
        t0 = time.monotonic()
        done = False
        try:
            while time.monotonic() - t0 < timeout and not STOP.is_set():
                sim_log = logs["simulator"].read_text(errors="replace")
                if "process time" in sim_log and "reached: F_max" in sim_log:
                    done = True
                    break
                if any(p.poll() is not None for p in procs.values()):
                    break
                time.sleep(0.2)                  # polling the logs of processes we wait for
        finally:
            for n in ("monitor", "planner", "simulator"):   # the monitor first, on purpose
                p = procs[n]
                if p.poll() is None:
                    p.send_signal(signal.SIGINT)
                p.wait(timeout=20)
                time.sleep(0.5)
        text = {n: log.read_text(errors="replace") for n, log in logs.items()}
    row["logs"] = text
    if not done:
        return {**row, "failed": "closed loop: no process end within the timeout",
                "log_tail": {n: t[-600:] for n, t in text.items()}}
    m = re.search(rf"reached: F_max = {NUM} N", text["simulator"])
    largest = float(m.group(1))
    m = re.search(rf"monitor up: abort at {NUM} N", text["monitor"])
    thr = float(m.group(1)) if m else math.nan
    start = re.search(rf"process starts at {NUM} s", text["simulator"])
    stop = re.search(rf"stopping from \w+ at {NUM} s, at rest in {NUM} s", text["planner"])
    aborted = "ABORT" in text["planner"] or "ABORT" in text["monitor"]
    reason = ""
    m = re.search(r"ABORT \((.*?)\)(?::|$)", text["planner"], re.M)
    if m:
        reason = m.group(1)
    abort_t = rest_t = None
    if stop and start:
        abort_t = float(stop.group(1)) - float(start.group(1))
        rest_t = abort_t + float(stop.group(2))
    largest_offline = offline.tension.max(axis=1)           # the plan's run without a monitor
    crossed = offline.t[largest_offline >= thr]
    t_cross = float(crossed[0]) if crossed.size else None
    row.update({
        "threshold_N": thr, "aborted": aborted, "aborted_before_threshold": False,
        "reason": reason, "largest_N": largest, "finished": True, "wall_time_s": None,
        "false_abort": bool(aborted and offline.F_max < thr),
        "missed": bool(offline.F_max >= thr and not aborted),
        **campaign.stop_intervals(t_cross, abort_t, rest_t),
        "max_tension_after_abort_N": largest if aborted else None,
    })
    row["tore"] = bool(largest >= cell.material.F_break)
    return row


if __name__ == "__main__":
    from rheo_shaping.params.cell import CellParams
    rng = random.Random(4742)
    cells = [campaign.sample_cell(CellParams(), rng) for _ in range(300)]
    idx = [int(x) for x in sys.argv[1].split(",")]
    reps = int(sys.argv[2])
    out = open(sys.argv[3], "a")
    tasks = [(i, r) for r in range(reps) for i in idx]
    doms = queue.Queue()
    for k in range(2): doms.put(70 + k)
    def one(t):
        i, r = t
        d = doms.get()
        try:
            row = run_case_logs(i, cells[i], prefix, d, 300.0)
        finally:
            doms.put(d)
        logs = row.pop("logs", {})
        ab = [l for l in logs.get("planner", "").splitlines() if "ABORT" in l or "state:" in l or "done" in l.lower()]
        reached = [l for l in logs.get("simulator", "").splitlines() if "reached" in l or "process starts" in l]
        out.write(json.dumps({"case": i, "rep": r, "aborted": row.get("aborted"), "reason": row.get("reason"), "planner": ab[-12:], "sim": reached, "row": {k: row.get(k) for k in ("false_abort","abort_to_rest_s","largest_N")}}) + "\n"); out.flush()
        print(i, r, row.get("aborted"), row.get("reason"), flush=True)
    with sc.lossy_namespace(5) as prefix, concurrent.futures.ThreadPoolExecutor(2) as pool:
        list(pool.map(one, tasks))
