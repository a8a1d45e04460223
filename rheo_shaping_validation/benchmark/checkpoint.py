"""A benchmark's finished cases kept as they come (JSON lines), so an interrupted run goes
on where it stopped (``diagnose-benchmark --save FILE``: ``FILE.partial.jsonl``)."""
from __future__ import annotations

import fcntl
import json
from pathlib import Path


def read_partial(path: str, key: dict) -> dict[int, dict]:
    """The cases of benchmark ``key`` already in the JSON-lines file ``path`` (index -> row;
    none if the file does not exist).  Lines of another benchmark are refused: a partial
    file belongs to one benchmark."""
    p = Path(path)
    if not p.exists():
        return {}
    done = {}
    for k, line in enumerate(p.read_text().splitlines(), 1):
        if not line.strip():
            continue
        try:
            entry = json.loads(line)
        except ValueError:
            continue                        # a line cut short by an interruption
        if entry.get("key") != key:
            raise ValueError(f"{path}, line {k}: a case of another benchmark "
                             f"({entry.get('key')}), not of this one ({key}): use another "
                             "--save file")
        done[int(entry["row"]["index"])] = entry["row"]
    return done


def append_partial(path: str, key: dict, row: dict) -> None:
    """One finished case appended to the JSON-lines file ``path`` (locked: workers of one
    host append to it at once)."""
    line = json.dumps({"key": key, "row": row}, default=float) + "\n"
    with open(path, "a") as fh:
        fcntl.flock(fh, fcntl.LOCK_EX)
        fh.write(line)
        fh.flush()
        fcntl.flock(fh, fcntl.LOCK_UN)
