"""Stepping from Python against the CLI: 1000 steps of the demo object, one thread, the two taking
turns for --rounds rounds; prints the medians (BENCHMARKS.md, "Python"). From the checkout:

    PYTHONPATH=build/python python3 scripts/bench_python.py [--cutsim build/cutsim] [--rounds 21]

CLI: the loop seconds of `cutsim run` (report.json: steps / steps_per_second, step() calls only).
Python: wall time around the whole loop, binding included: sim.step(1000), and a Python loop of
1000 sim.step() calls that reads the tool force after each (a haptic loop). Every measurement is a
fresh process, as the CLI's is.
"""
import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import cutsim

SCENE = str(Path(__file__).resolve().parents[1] / "assets" / "scenes" / "demo.json")
STEPS = 1000


def child(kind, duration):
    """One Python measurement, printed as JSON: sim.step(1000), or a loop of step() and tool_force()."""
    import numpy  # noqa: F401  (imported by any caller that reads arrays; not inside the timing)

    sim = cutsim.Simulation(SCENE, set=[f"duration={duration!r}", "capture.enabled=false"], threads=1)
    t = time.perf_counter()
    if kind == "block":
        assert sim.step(STEPS) == STEPS
    else:
        for _ in range(STEPS):
            sim.step()
            sim.tool_force(0)
    seconds = time.perf_counter() - t
    assert sim.steps == STEPS
    print(json.dumps({"seconds": seconds, "state_hash": sim.state_hash()}))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--cutsim", default="build/cutsim")
    ap.add_argument("--rounds", type=int, default=21)
    ap.add_argument("--child", choices=["block", "loop"], help=argparse.SUPPRESS)
    ap.add_argument("--duration", type=float, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        return child(args.child, args.duration)
    duration = (STEPS - 0.5) * cutsim.Simulation(SCENE, threads=1).dt
    sets = [f"duration={duration!r}", "capture.enabled=false"]
    cli, block, loop = [], [], []
    hashes = set()
    with tempfile.TemporaryDirectory() as tmp:

        def run_cli():
            cmd = [args.cutsim, "run", SCENE, "--out", tmp, "--no-render", "--quiet", "--threads", "1"]
            subprocess.run(cmd + [a for s in sets for a in ("--set", s)], check=True)
            r = json.loads((Path(tmp) / "report.json").read_text())
            assert r["steps"] == STEPS, r["steps"]
            cli.append(r["steps"] / r["steps_per_second"])
            hashes.add(r["state_hash"])

        def run_python(kind, out):
            # a fresh process, as the CLI's: a long-lived one that waited for the CLI is scheduled
            # differently on a shared machine
            p = subprocess.run([sys.executable, __file__, "--child", kind, "--duration", repr(duration)],
                               check=True, capture_output=True, text=True)
            r = json.loads(p.stdout)
            out.append(r["seconds"])
            hashes.add(r["state_hash"])

        def run_block():
            run_python("block", block)

        def run_loop():
            run_python("loop", loop)

        sides = [run_cli, run_block, run_loop]
        for k in range(args.rounds):
            for side in sides[k % 3 :] + sides[: k % 3]:  # each side first in turn
                side()
    assert len(hashes) == 1, hashes  # the same run everywhere
    c = statistics.median(cli)
    print(f"{STEPS} steps of the demo object, 1 thread, median of {args.rounds} rounds")
    for name, v in (("cli (report loop time)", cli), ("python sim.step(1000)", block),
                    ("python loop step()+tool_force()", loop)):
        m = statistics.median(v)
        print(f"  {name:34s} {1e3 * m:8.2f} ms  {100 * (m / c - 1):+6.1f}%  (min {1e3 * min(v):.2f} ms)")


if __name__ == "__main__":
    main()
