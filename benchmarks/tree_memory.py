"""Peak memory of a process and all its descendants, summed (Linux /proc).

    .venv/bin/python benchmarks/tree_memory.py -- COMMAND [ARGS...]
        [--json F] [--interval-s 0.2]

Runs COMMAND, samples the resident set size (RSS) of it and of every process
it started, every --interval-s seconds, and prints (and writes as JSON) the
command's wall time, its exit code, and the peak of the summed RSS: what the
machine must hold at once. (`/usr/bin/time -v` reports the largest single
process instead.) Also importable: `run_sampled(argv)`.
"""

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

from regrasp_drake import atomic_io


def _children() -> dict:
    """pid -> parent pid, for every process."""
    parents = {}
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            text = stat.read_text()
        except OSError:
            continue  # exited
        # The command name is in parentheses and may hold spaces.
        fields = text[text.rindex(")") + 2:].split()
        parents[int(stat.parent.name)] = int(fields[1])
    return parents


def _rss_bytes(pid: int) -> int:
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) * 1024
    except OSError:
        pass  # exited
    return 0


def tree_rss_bytes(root: int) -> int:
    """The summed RSS of `root` and its descendants."""
    parents = _children()
    tree, frontier = {root}, [root]
    while frontier:
        pid = frontier.pop()
        for child, parent in parents.items():
            if parent == pid and child not in tree:
                tree.add(child)
                frontier.append(child)
    return sum(_rss_bytes(pid) for pid in tree)


def run_sampled(argv, interval_s: float = 0.2, **popen) -> dict:
    """Runs argv to its end; returns wall_s, returncode, peak_tree_rss_bytes
    and peak_tree_rss_gib."""
    t0 = time.perf_counter()
    process = subprocess.Popen(argv, **popen)
    peak = 0
    while process.poll() is None:
        peak = max(peak, tree_rss_bytes(process.pid))
        time.sleep(interval_s)
    return {"command": list(argv), "returncode": process.returncode,
            "wall_s": round(time.perf_counter() - t0, 1),
            "peak_tree_rss_bytes": peak,
            "peak_tree_rss_gib": round(peak / 2**30, 3)}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--json", type=Path)
    parser.add_argument("--interval-s", type=float, default=0.2)
    parser.add_argument("command", nargs=argparse.REMAINDER)
    args = parser.parse_args(argv)
    command = args.command[1:] if args.command[:1] == ["--"] else args.command
    if not command:
        parser.error("expected a command after --")
    if not args.interval_s > 0:
        parser.error(f"--interval-s {args.interval_s}: expected > 0")
    report = run_sampled(command, args.interval_s)
    print(json.dumps(report, indent=1))
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        atomic_io.write_json(args.json, report)
    return report["returncode"]


if __name__ == "__main__":
    sys.exit(main())
