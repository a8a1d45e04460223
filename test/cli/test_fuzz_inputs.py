"""What users hand the program cannot break it: a short run of benchmarks/fuzz_inputs.py
(fuzzed params files into the core loader and `simulate`, fuzzed records into the reader
and `diagnose`) gives no traceback and no write outside the output folder. The long run
(2,000 params files, 500 records, the node executables) is the benchmark itself."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

SCRIPT = Path(__file__).resolve().parents[2] / "benchmarks" / "fuzz_inputs.py"


def test_short_fuzz_run_has_no_traceback_and_no_stray_write():
    proc = subprocess.run([sys.executable, str(SCRIPT), "--params", "200", "--records", "30",
                           "--cli-every", "40", "--seed", "7", "--record-seconds", "10",
                           "--json"], capture_output=True, text=True, timeout=900)
    assert proc.returncode in (0, 1), proc.stderr[-3000:]
    summary = json.loads(proc.stdout.strip().splitlines()[-1])
    assert summary["failures"] == 0, summary["first_failures"]
    counts = summary["counts"]
    assert counts["params"]["ok"] + counts["params"]["refused"] == 200
    assert counts["params"]["refused"] > 0 and counts["records"]["refused"] > 0
    assert counts["records"]["ok"] + counts["records"]["refused"] == 30
