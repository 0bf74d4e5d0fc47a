#!/usr/bin/env python3
"""Results for BENCHMARKS.md from runs of the cutsim program itself (not `cutsim bench`), as JSON on
stdout with the machine they ran on, in the form `cutsim bench --json` gives it (scripts/bench_tables.py
draws the tables). From the checkout:

    scripts/bench_runs.py tetra > docs/bench/tetra_heldout.json
        `cutsim tetra` on the data folder's surfaces it was not tuned for, one after the other
    scripts/bench_runs.py run SCENE --out DIR [cutsim run options] > docs/bench/NAME.json
        `cutsim run SCENE --out DIR ...` once; its report.json without the run's per-step records
    scripts/bench_runs.py runs SCENE --out DIR --vary KEY=V1,V2,... [cutsim run options] > docs/bench/NAME.json
        `cutsim run SCENE --set KEY=V ...` once per value, in turn (DIR/0, DIR/1, ...); with each run
        of an object.tetra scene, the report of its mesh (built in a cache of its own, not timed)
    scripts/bench_runs.py blade-scale --out DIR > docs/bench/blade_scale.json
        blade.json's stroke on finer livers (TetGen meshes of the shipped surface, 16k to 106k tets)
        and on lattices, one thread, without frames (about 15 minutes)

machine: {cpu, cores, load_average, load_average_end}, the 1, 5 and 15 minute load averages as the
runs started and as they ended.
"""

import argparse
import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

# The held-out surfaces (DATA/surface, in their own units; the shipped liver in inches, scaled to m)
# and the edge length asked of each: the default mesher's, for 20-40k tets; TetGen's, the sizes it
# was first measured at (it keeps the surface's triangles, so it makes more tets at a size).
TETRA_SURFACES = [("DATA/surface/sofa_liver2.obj", 1, 0.06, 0.11),
                  ("DATA/surface/sofa_Armadillo_verysimplified.obj", 1, 0.38, 0.545),
                  ("DATA/surface/igl_decimated-knight.off", 1, 0.018, 0.026),
                  ("DATA/surface/sofa_Bunny.stl", 1, 0.336, 0.535),
                  ("DATA/surface/igl_bunny.off", 1, 0.0056, 0.011),
                  ("assets/meshes/sofa_liver.obj", 0.0254, 0.0046, 0.0055)]
TETRA_MATERIAL = ["--E", "30000", "--nu", "0.3", "--rho", "1000"]

# What a run's report keeps here: the result, its size and its times (no per-step records, no paths).
REPORT_KEYS = ["name", "status", "pieces", "piece_volumes", "sim_time", "steps", "threads", "wall_time",
               "real_time_factor", "stages", "frames", "state_hash", "capture"]
MESH_KEYS = ["elements", "elements_final", "nodes", "nodes_final"]

# blade.json's object swapped: TetGen livers of the shipped surface made at load (object.tetra, the
# sizes in m after the scale; about 16k, 40k and 106k tets), the liver in MI lattices, and a box.
BLADE_LIVER = '"scale": 0.0254, "visual": "../meshes/sofa_liver-smooth.obj"'
BLADE_OBJECTS = [
    ("liver, TetGen 0.0112", '{"tetra": {"surface": "../meshes/sofa_liver.obj", "size": 0.0112, '
     '"mesher": "tetgen"}, ' + BLADE_LIVER + '}'),
    ("liver, TetGen 0.0065", '{"tetra": {"surface": "../meshes/sofa_liver.obj", "size": 0.0065, '
     '"mesher": "tetgen"}, ' + BLADE_LIVER + '}'),
    ("liver, TetGen 0.0041", '{"tetra": {"surface": "../meshes/sofa_liver.obj", "size": 0.0041, '
     '"mesher": "tetgen"}, ' + BLADE_LIVER + '}'),
    ("liver, MI 16 cells", '{"surface": {"path": "../meshes/sofa_liver.obj", "cells": 16}, "scale": 0.0254}'),
    ("liver, MI 32 cells", '{"surface": {"path": "../meshes/sofa_liver.obj", "cells": 32}, "scale": 0.0254}'),
]


def machine():
    """The CPU's model name and widest vector instructions, the cores, the load averages now (as
    bench/machine.cpp records them)."""
    cpu, vector = "", ""
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as f:
            lines = f.readlines()
        cpu = next((line.split(":", 1)[1].strip() for line in lines if line.startswith("model name")), "")
        flags = next((line.split(":", 1)[1].split() for line in lines if line.startswith("flags")), [])
        vector = next((name for flag, name in (("avx512f", "AVX-512"), ("avx2", "AVX2"), ("sse4_2", "SSE4.2"))
                       if flag in flags), "")
    except OSError:
        pass
    return {"cpu": cpu, "vector": vector, "cores": os.cpu_count(), "load_average": list(os.getloadavg())}


def tetra(args):
    runs = []
    for mesher in ("auto", "tetgen"):
        for path, scale, size_auto, size_tetgen in TETRA_SURFACES:
            size = size_auto if mesher == "auto" else size_tetgen
            surface = path.replace("DATA", args.data)
            cmd = [args.cutsim, "tetra", surface, "--size", str(size), "--scale", str(scale), "--mesher", mesher,
                   "--json"] + TETRA_MATERIAL
            start = time.perf_counter()
            out = subprocess.run(cmd, cwd=ROOT, check=True, capture_output=True, text=True).stdout
            r = json.loads(out)
            r["surface"] = Path(path).name  # the file's name, not this machine's path to it
            r["mesher_option"] = mesher
            r["process_seconds"] = time.perf_counter() - start
            runs.append(r)
    return {"command": "cutsim tetra SURFACE --size H --scale S --mesher M --json " + " ".join(TETRA_MATERIAL),
            "runs": runs}


def run(args, rest):
    cmd = [args.cutsim, "run", args.scene, "--out", args.out, "--quiet"] + rest
    code = subprocess.run(cmd, cwd=ROOT).returncode
    rep, j = report_of(args.out, REPORT_KEYS)
    j["cuts"] = len(rep.get("cuts", []))
    j["command"] = " ".join(["cutsim run", args.scene, "--out", args.out] + rest)
    j["exit_code"] = code
    return j


def runs(args, rest):
    key, _, values = args.vary.partition("=")
    if not key or not values:
        raise SystemExit("--vary: KEY=V1,V2,... expected")
    env = dict(os.environ, CUTSIM_CACHE=str(ROOT / args.out / "cache"))
    shutil.rmtree(ROOT / args.out / "cache", ignore_errors=True)
    out = []
    for i, v in enumerate(values.split(",")):
        d = f"{args.out}/{i}"
        cmd = [args.cutsim, "run", args.scene, "--out", d, "--quiet", "--set", f"{key}={v}"] + rest
        tetra = None
        with open(ROOT / args.scene, encoding="utf-8") as f:
            if "tetra" in json.load(f).get("object", {}):  # the mesh first, so its making is not timed
                subprocess.run(cmd[:4] + [d + "-mesh"] + cmd[5:] + ["--no-render", "--set", "duration=0.002"],
                               cwd=ROOT, check=True, env=env)
                with open(ROOT / (d + "-mesh") / "report.json", encoding="utf-8") as g:
                    t = json.load(g)["tetra"]
                tetra = {k: t[k] for k in ("mesher", "size", "tets", "dt_after", "step_quality", "seconds") if k in t}
        code = subprocess.run(cmd, cwd=ROOT, env=env).returncode
        rep, j = report_of(d, REPORT_KEYS + ["inverted"])
        if tetra:
            j["tetra"] = tetra
        j["value"] = v
        j["exit_code"] = code
        out.append(j)
    return {"command": " ".join(["cutsim run", args.scene, "--set", f"{key}=V"] + rest), "key": key, "runs": out}


def report_of(out_dir, keys):
    with open(ROOT / out_dir / "report.json", encoding="utf-8") as f:
        rep = json.load(f)
    j = {k: rep[k] for k in keys if k in rep}
    j["mesh"] = {k: rep["mesh"][k] for k in MESH_KEYS if k in rep.get("mesh", {})}
    return rep, j


def blade_scale(args, rest):
    """Each object twice: once to build its mesh (object.tetra's cache; not timed), then the run (other
    options go to cutsim run)."""
    runs = []
    # a cache of its own: each mesh is built here, so its report is there to keep
    env = dict(os.environ, CUTSIM_CACHE=str(ROOT / args.out / "cache"))
    shutil.rmtree(ROOT / args.out / "cache", ignore_errors=True)
    for name, obj in BLADE_OBJECTS:
        out = f"{args.out}/{len(runs)}"
        common = [args.cutsim, "run", "assets/scenes/blade.json", "--out", out, "--quiet", "--no-render",
                  "--threads", "1", "--set", "object=" + obj]
        tetra = None
        if "tetra" in obj:  # the mesh built (or found in the cache) by a run of one step
            subprocess.run(common[:4] + [out + "-mesh"] + common[5:] + ["--set", "duration=0.002"], cwd=ROOT,
                           check=True, env=env)
            with open(ROOT / (out + "-mesh") / "report.json", encoding="utf-8") as f:
                t = json.load(f)["tetra"]
            tetra = {k: t[k] for k in ("mesher", "size", "tets", "dt_after", "step_quality", "seconds") if k in t}
        code = subprocess.run(common + rest, cwd=ROOT, env=env).returncode
        rep, j = report_of(out, REPORT_KEYS + ["strokes"])
        if tetra:
            j["tetra"] = tetra
        energy = rep.get("energy", [])
        j["kinetic_end"] = energy[-1]["kinetic"] if energy else None
        j["object"] = name
        j["exit_code"] = code
        runs.append(j)
    return {"command": " ".join(["cutsim run assets/scenes/blade.json --no-render --threads 1 --set object=OBJECT"]
                                + rest),
            "runs": runs}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cutsim", default="build/cutsim", help="the program, relative to the checkout")
    ap.add_argument("--data", default="../shared/data", help="the third-party meshes' folder, relative to the checkout")
    sub = ap.add_subparsers(dest="what", required=True)
    sub.add_parser("tetra", help="cutsim tetra on the held-out surfaces")
    r = sub.add_parser("run", help="cutsim run SCENE once (other options go to cutsim run)")
    r.add_argument("scene")
    r.add_argument("--out", required=True)
    v = sub.add_parser("runs", help="cutsim run SCENE once per value of a key (other options go to cutsim run)")
    v.add_argument("scene")
    v.add_argument("--out", required=True)
    v.add_argument("--vary", required=True, help="KEY=V1,V2,...")
    b = sub.add_parser("blade-scale", help="blade.json's stroke on finer livers and on lattices (other options "
                                           "go to cutsim run)")
    b.add_argument("--out", required=True)
    args, rest = ap.parse_known_args()
    if args.what == "tetra" and rest:
        ap.error(f"unknown arguments: {' '.join(rest)}")
    m = machine()
    j = {"tetra": lambda: tetra(args), "blade-scale": lambda: blade_scale(args, rest), "runs": lambda: runs(args, rest),
         "run": lambda: run(args, rest)}[args.what]()
    if "runs" in j and args.what != "tetra":
        j["exit_code"] = max(r.get("exit_code", 0) for r in j["runs"])
    j["machine"] = m
    j["machine"]["load_average_end"] = list(os.getloadavg())
    json.dump(j, sys.stdout, indent=2)
    sys.stdout.write("\n")
    return 0 if j.get("exit_code", 0) == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
