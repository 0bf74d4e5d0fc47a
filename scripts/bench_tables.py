#!/usr/bin/env python3
"""BENCHMARKS.md's tables from the results in docs/bench (JSON), so that the page shows the data.

Each generated table sits between two comments in BENCHMARKS.md,

    <!-- generated: NAME -->
    | ... the table ... |
    <!-- end generated -->

and this script rewrites what is between them: the table NAME (TABLES below), each drawn from one
result file. scripts/bench.sh runs it after the benchmarks; the test Format.BenchTables runs --check.

    scripts/bench_tables.py           rewrite BENCHMARKS.md's generated tables in place
    scripts/bench_tables.py --check   exit 1, with a diff, when BENCHMARKS.md differs from them
"""

import argparse
import difflib
import json
import math
import re
import statistics
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PAGE = ROOT / "BENCHMARKS.md"
DATA = ROOT / "docs" / "bench"

BLOCK = re.compile(r"(<!-- generated: ([\w-]+) -->\n)(.*?)(<!-- end generated -->)", re.S)


def load(name):
    with open(DATA / name, encoding="utf-8") as f:
        return json.load(f)


def table(header, rows):
    """A Markdown table: a header row, its rule, the rows (lists of cells; an empty cell is "| |")."""

    def line(cells):
        return "|" + "|".join(f" {c} " if c else " " for c in cells) + "|"

    return "\n".join([line(header), "|" + "---|" * len(header)] + [line(r) for r in rows]) + "\n"


def ran_on(*results):
    """A line under a table of wall times: the machine and its 1-minute load average when each run
    started and ended (the result's "machine"), lowest to highest."""
    loads = [x for j in results for x in (j["machine"]["load_average"][0], j["machine"]["load_average_end"][0])]
    m = results[0]["machine"]
    cpu = m["cpu"] + (f", {m['vector']}" if m.get("vector") else "")
    return f"\n{m['cores']} cores ({cpu}), load average {span(loads, tenths)} over the run.\n"


def decimals(v, n):
    return f"{v:.{n}f}"


def tenths(v):
    return decimals(v, 1)


def span(values, fmt):
    """The lowest and highest of values, formatted; one value when the two read the same."""
    lo, hi = fmt(min(values)), fmt(max(values))
    return lo if lo == hi else f"{lo}-{hi}"


def ms(seconds):
    """Milliseconds, two decimals below 10 ms, one above."""
    v = 1e3 * seconds
    return decimals(v, 2 if v < 10 else 1)


def percent(fraction, n=3):
    return f"{100 * fraction:.{n}f}%"


def microseconds(seconds):
    """Microseconds to three significant digits."""
    return f"{1e6 * seconds:.3g} us"


# ---- bench scale: docs/bench/scale.json ----

SCALE_KINDS = [("tetgen", "TetGen"), ("mi", "MI")]
SCALE_SCENES = ["sag", "probe", "cuts", "blade"]


def scale_runs(j, kind):
    """One-thread runs of a mesh kind that gave stage times, by element count: {elements: {scene: run}}."""
    out = {}
    for r in j["runs"]:
        if r["mesh"] == kind and r["threads"] == 1 and "stages" in r:
            out.setdefault(r["elements"], {})[r["scene"]] = r
    return dict(sorted(out.items()))


def scale_step():
    """Milliseconds per step on one thread, each scene, per mesh; the blade's cut stage beside it."""
    j = load("scale.json")
    rows = []
    for kind, label in SCALE_KINDS:
        for elements, runs in scale_runs(j, kind).items():
            cells = [label, f"{elements:,}"]
            for scene in SCALE_SCENES:
                r = runs.get(scene)
                if r is None:
                    cells.append("")
                elif scene == "blade":
                    cells.append(f"{ms(r['seconds_per_step'])} ({ms(r['stages']['cut'])})")
                else:
                    cells.append(ms(r["seconds_per_step"]))
            cells.append(f"{round(runs['sag']['bytes_per_element']):,}" if "sag" in runs else "")
            rows.append(cells)
    return table(["mesh", "elements", "sag", "probe", "cuts", "blade (cut stage)", "bytes / element"], rows)


def scale_exponents():
    """Fitted exponents of the cost per step against elements, one thread."""
    j = load("scale.json")
    stages = ["step", "forces", "contact", "cut", "timestep"]
    rows = []
    for kind, label in SCALE_KINDS:
        for scene in SCALE_SCENES:
            for f in j["exponents"]:
                if f["mesh"] == kind and f["scene"] == scene and f["threads"] == 1:
                    e = f["exponents"]
                    rows.append([label, scene] + [decimals(e[s], 2) if s in e else "" for s in stages])
    return table(["mesh", "scene", "step", "forces", "contact", "cut", "timestep"], rows)


# ---- bench accuracy: docs/bench/accuracy_1pct_paired.json ----


def accuracy_paired():
    """The explicit runs that took turns with the CG run under 1% error, and that run."""
    j = load("accuracy_1pct_paired.json")
    implicit = j["summary"]["cantilever_frequency"]["paired_implicit"]
    c = next(p for p in j["paired"] if p["implicit"] == implicit)
    dt = {p["config"]: p["dt"] for p in j["points"]}
    rows = []
    for e in c["explicit"]:
        name = "explicit, single-precision forces" if " single " in e["config"] else "explicit, double"
        rows.append([name, microseconds(dt[e["config"]]), percent(e["error"]),
                     decimals(e["cost"], 1), f"**{e['ratio']:.1f}x**"])
    rows.append(["backward Euler, CG", microseconds(dt[implicit]), percent(c["implicit_error"]),
                 decimals(c["implicit_cost"], 1), "1"])
    return table(["", "dt", "error", "wall / sim s", "CG / this"], rows)


NOTCH_ROUTES = {"xfem row_sum": "XFEM, row sum", "xfem weighted_diagonal": "XFEM, weighted diagonal",
                "xfem enrichment": "XFEM, enrichment", "xfem enrichment+floor": "XFEM + floor",
                "xfem enrichment+hybrid": "XFEM + hybrid", "subdivision": "subdivision",
                "subdivision+improve": "subdivision + improve (budgeted)",
                "subdivision+improve-full": "subdivision + improve (full)", "subdivision+hybrid": "subdivision + hybrid"}


def accuracy_notch():
    """The notched cantilever per route: elements, the exact step over the uncut bar's, the static
    tip and frequency errors against the converged conforming notch, ms per cut; the conforming
    notch meshes last (boxes of cubes in 6 tets each)."""
    j = load("accuracy_notch.json")
    err = {(p["problem"], p["config"]): p["error"] for p in j["points"]}
    refs = j["references"]["cantilever_notch_static"]
    rows = []
    for r in refs["xfem"] + refs["subdivision"]:
        route, mesh, f = r["config"].rsplit(" ", 2)
        label = NOTCH_ROUTES[route] + (f" ({r['matched']} matched)" if route.endswith("hybrid") else "")
        rows.append([mesh, label, str(r["tets"]), decimals(r["dt_ratio"], 4),
                     decimals(err[("cantilever_notch_static", r["config"])], 5),
                     decimals(err[("cantilever_notch_frequency", r["config"])], 5), decimals(1e3 * r["cut_seconds"], 2)])
    rows.sort(key=lambda c: [int(x) for x in c[0].split("x")])  # by mesh, each mesh's routes in run order
    conforming = sorted({p["config"] for p in j["points"] if p["config"].startswith("conforming notch")},
                        key=lambda c: int(c.split()[2].split("x")[0]))
    meshes = [c.split()[2] for c in conforming]
    rows.append([" / ".join(meshes), "conforming notch",
                 " / ".join(str(6 * math.prod(int(x) for x in m.split("x"))) for m in meshes), "(reference meshes)",
                 " / ".join(decimals(err[("cantilever_notch_static", c)], 5) for c in conforming),
                 " / ".join(decimals(err[("cantilever_notch_frequency", c)], 5) for c in conforming), "-"])
    return table(["mesh", "route", "tets", "step ratio", "static tip error", "frequency error", "ms per cut"], rows) + \
        ran_on(j)


# ---- bench mi-bar: docs/bench/mi_bar.json ----


def mi_bar():
    """Table 6.1: the exact step after the cut over the uncut bar's, per share kept and method."""
    rows = load("mi_bar.json")
    uncut = next(r["dt_exact"] for r in rows if r["kept"] == 1 and r["method"] == "subdivision")
    by = {(r["kept"], r["method"]): r for r in rows}
    out = []
    for kept in sorted({r["kept"] for r in rows if r["kept"] < 1}, reverse=True):
        cells = [f"{100 * kept:.0f}%"]
        for method in ["remesh", "subdivision", "mi"]:
            r = by[(kept, method)]
            cell = decimals(r["dt_exact"] / uncut, 3)
            if r.get("added_mass_fraction", 0) > 0:
                mantissa, exponent = f"{r['added_mass_fraction']:.1e}".split("e")
                cell += f" ({mantissa}e{int(exponent)} of the mass added)"
            cells.append(cell)
        out.append(cells)
    return table(["kept", "TetGen remesh", "conforming subdivision", "MI (default: mass added where needed)"], out)


# ---- bench step and cutsim_bullet_bench: docs/bench/step.json, bullet_step.json, bullet_step_unrotated.json ----


def mega(v):
    """Millions, three significant digits: 27.9M, 18.0M."""
    return f"{v / 1e6:#.3g}".rstrip(".") + "M"


def step_bullet():
    """Tet-steps per second of cutsim and Bullet, one thread, the ratios, and the ratio from the rest shape."""
    rotated = load("bullet_step.json")["runs"]
    rest = {r["tets"]: r for r in load("bullet_step_unrotated.json")["runs"]}
    rows = []
    for r in rotated:
        t = r["tet_steps_per_second"]
        r0 = rest.get(r["tets"])
        rows.append([f"{r['tets']:,}", mega(t["cutsim_double"]), mega(t["cutsim_single"]), mega(t["bullet"]),
                     mega(t["bullet_damped"]), f"**{r['ratio_cutsim_double_to_bullet']:.1f}x**",
                     f"{r['ratio_cutsim_double_to_bullet_damped']:.1f}x",
                     f"{r0['ratio_cutsim_double_to_bullet']:.1f}x" if r0 else ""])
    return table(["tets", "cutsim double", "cutsim single", "Bullet", "Bullet, default damping", "cutsim / Bullet",
                  "cutsim / Bullet damped", "cutsim / Bullet from the rest shape"], rows) + \
        ran_on(load("bullet_step.json"), load("bullet_step_unrotated.json"))


def step_threads():
    """cutsim's tet-steps per second on 1 and 2 threads, double and single, and the element kernel's share."""
    j = load("step.json")
    by = {}
    for r in j["runs"]:
        by.setdefault(r["tets"], {})[(r["threads"], r["precision"])] = r
    rows = []
    for tets, runs in sorted(by.items()):
        def rate(th, p):
            return mega(runs[(th, p)]["tet_steps_per_second"])

        share = runs[(1, "double")]["stages"]["element"]
        rows.append([f"{tets:,}", f"{rate(1, 'double')} / {rate(1, 'single')}",
                     f"{rate(2, 'double')} / {rate(2, 'single')}", f"{100 * share:.0f}%"])
    return table(["tets", "1 thread double / single", "2 threads double / single",
                  "element kernel share (1 thread, double)"], rows) + ran_on(j)


# ---- bench stability: docs/bench/stability.json ----

PLAIN = ["symplectic_euler", "central_difference", "newmark"]


def joined(values):
    """One value when all agree, else each, separated by slashes."""
    return values[0] if len(set(values)) == 1 else " / ".join(values)


def stability_sweeps():
    """Largest stable fraction of the exact step per mesh: the plain schemes, alpha_e, alpha_e with a margin."""
    by = {}
    for s in load("stability.json")["sweeps"]:
        by.setdefault(s["mesh"], {})[(s["integrator"], s["scheme"])] = s

    def frac(s):
        f = s["largest_stable_fraction"]
        return decimals(f, 3) if f < 1.005 else f"{f:.3g}"

    rows = []
    for mesh, runs in by.items():
        plain = joined([frac(runs[(i, "plain")]) for i in PLAIN])
        name = mesh.split(" (")[0]  # "liver (sofa_liver.msh)": the data file is the section's
        rows.append([f"{name} ({next(iter(runs.values()))['tets']} tets)", plain,
                     frac(runs[("symplectic_euler", "alpha_e")]), frac(runs[("symplectic_euler", "alpha_e_0.95")])])
    return table(["mesh", "symplectic Euler, central difference, Newmark", "alpha_e (eq. 3.16)",
                  "alpha_e, margin 0.95"], rows)


def stability_after_cuts():
    """After cuts, per mesh and lumping: the exact step over the uncut one, the largest stable fraction."""
    by = {}
    for s in load("stability.json")["after_cuts"]:
        by.setdefault(s["mesh"], []).append(s)
    rows = []
    for mesh, runs in by.items():
        rows.append([mesh, " / ".join(r["lumping"].replace("_", " ") for r in runs),
                     " / ".join(decimals(r["dt_ratio"], 3) for r in runs),
                     " / ".join(decimals(r["largest_stable_fraction"], 3) for r in runs)])
    return table(["mesh", "lumping", "exact dt cut / uncut", "largest stable fraction"], rows)


FLOORS = {"-": ("none", "none"), "local": ("local (R1R)", "local (R1R)"),
          "certified": ("certified (local, then exact + keepStep)", "certified"),
          "global": ("global (keepStep alone)", "global"),
          "hybrid": ("hybrid (elements under the floor matched, then certified)", "hybrid")}


def stability_floor():
    """Random cut sequences with stretch limiting, per object and floor: the step kept and what it cost."""
    j = load("stability.json")
    rows = []
    seen = []
    for r in j["random_cuts"]:
        if r["min_stretch"] == 0:
            continue
        if r["object"] not in seen:
            seen.append(r["object"])
        fl = r["floor"]
        label = FLOORS[fl][0 if len(seen) == 1 else 1]
        none = fl == "-"
        rows.append([r["object"], label, decimals(r["min_dt_ratio"], 3),
                     "" if none else (f"{r['cuts_below_floor']} of {r['cuts']}" if r["cuts_below_floor"] else "0"),
                     str(r["cuts_topped_up"]) if fl in ("certified", "hybrid") else "",
                     "" if none else percent(r["max_added_mass"]),
                     "" if none else f"{ms(r['mean_floor_seconds'])} / {ms(r['max_floor_seconds'])}"])
    return table(["object", "floor", "min dt ratio", "under floor", "topped up", "max mass added", "ms per cut"],
                 rows) + ran_on(j)


def stability_500():
    """The step floor through 500 random sequences per object (the stress test), per object and floor."""
    j = load("random_cuts_500.json")
    rows = []
    for obj in ("liver", "bar"):
        for fl in ("certified", "hybrid"):
            r = next(r for r in j["runs"] if r["object"] == obj and r["floor"] == fl)
            mass = percent(r["max_added_mass"])
            rows.append([obj, fl, str(r["cuts"]), decimals(r["min_dt_ratio"], 3),
                         f"**{mass}**" if fl == "hybrid" else mass, str(r["cuts_topped_up"])])
    return table(["object", "floor", "cuts", "min dt ratio", "max mass added", "topped up"], rows) + ran_on(j)


# ---- cutsim dt --json: docs/bench/dt_liver.json, dt_armadillo.json ----

# Thesis Table 4.3, the values it prints for each mesh: exact, R1R, Hp, Hs, Le / c_p [ms].
THESIS_TABLE_43 = {"liver": "0.4510, 0.4514, 0.4189, 0.4838, 0.1630",
                   "armadillo": "0.0642, 0.0642, 0.0879, 0.1025, 0.0061"}


def dt_table43():
    """Table 4.3: each estimator's smallest step over the elements against the exact step, per mesh."""
    rows = []
    for name in THESIS_TABLE_43:
        j = load(f"dt_{name}.json")

        def v(key):
            return f"{1e3 * j[key]:.4f}"

        rows.append([f"{name}, {j['tets']} tets", v("dt_exact") + " ms", v("dt_certified") + " ms", v("dt_r1r"),
                     v("dt_hp"), v("dt_hs"), v("dt_le"), THESIS_TABLE_43[name]])
    return table(["mesh", "exact (Lanczos)", "certified (Gershgorin)", "R1R", "Hp", "Hs", "Le / c_p",
                  "thesis Table 4.3"], rows)


# ---- bench improve: docs/bench/improve.json ----


def improve_table():
    """Table 5.1: the exact step of each data mesh after each method."""
    j = load("improve.json")
    rows = []
    for m in j["meshes"]:
        dt0 = m["dt_exact"]

        def cell(name, bold=False, detail=False):
            r = m["methods"].get(name)
            if r is None:
                return ""
            if "error" in r:
                return "fails"
            gain = f"{r['gain']:.2f}x"
            tets = f", {r['tets']} tets" if r["tets"] != m["tets"] else ""
            if detail:
                head = f"{1e3 * r['dt_exact']:.4f} ms, {gain}"
                return (f"**{head}**" if bold else head) + tets + \
                    f", vol {100 * r['volume_change']:+.2f}%, boundary {100 * r['boundary_distance_rel']:.2f}%"
            if gain == "1.00x":
                return gain
            return (f"{1e3 * r['dt_exact']:.4f} ms, " if name == "gmsh" else "") + gain + tets

        rows.append([f"{m['mesh']} ({m['scale']:g})", str(m["tets"]), f"{1e3 * dt0:.4f} ms",
                     cell("cutsim", bold=True, detail=True), cell("tetgen -rO10/7"), cell("gmsh"),
                     cell("cgal remesh")])
    return table(["mesh (scale)", "tets", "input dt", "cutsim", "TetGen -rO10/7", "Gmsh", "CGAL remesh"], rows) + \
        ran_on(j)


def improve_time():
    """Gain against time, wall clock only."""
    j = load("improve.json")
    rows = []
    for m in j["meshes"]:
        t = j["gain_against_time"][m["mesh"]]
        rows.append([m["mesh"]] + [decimals(t[k], 2) for k in ("gain_at_0.1s", "gain_at_1s", "gain_at_10s")])
    return table(["mesh", "0.1 s", "1 s", "10 s"], rows)


def improve_speed():
    """The improver's seconds at its defaults per mesh and thread count (medians of the rounds), as
    found and with a loop on the other core, and per 10,000 input elements; the fastest as found per
    mesh in bold."""
    j = load("improve_speed.json")
    by = {}
    for r in j["runs"]:
        by.setdefault(r["mesh"], {}).setdefault(r["threads"], {}).setdefault(r["load"], []).append(r)
    rows = []
    for mesh, counts in by.items():
        tets = next(iter(counts.values()))["idle"][0]["tets"]

        def med(runs):
            return statistics.median(r["seconds"] for r in runs) if runs else None

        fastest = min(med(c["idle"]) for c in counts.values())
        for k, (threads, c) in enumerate(sorted(counts.items())):
            cells = [f"{mesh} ({tets} tets)" if k == 0 else mesh, str(threads)]
            for kind in ("idle", "busy"):
                t = med(c.get(kind, []))
                if t is None:
                    cells += ["", ""]
                    continue
                per = f"{t * 1e4 / tets:.2f} s"
                cells += [f"{t:.3f} s", f"**{per}**" if kind == "idle" and t == fastest else per]
            rows.append(cells)
    return table(["mesh", "threads", "as found", "per 10k tets", "a loop on the other core", "per 10k tets"], rows) + \
        ran_on(j)


# ---- cutsim_bench (Google Benchmark, console output): docs/bench/cutsim_bench.txt ----

TIME_UNITS = {"ns": 1e-9, "us": 1e-6, "ms": 1e-3, "s": 1.0}
COUNTER = re.compile(r"(-?[0-9.]+(?:e[-+]?[0-9]+)?)([kMG]?)")


def google_benchmark(name):
    """A Google Benchmark console output: ({benchmark name: (real time [s], {counter: value})}, the
    1-minute load average its header gives)."""
    rows, load_avg = {}, None
    for line in (DATA / name).read_text(encoding="utf-8").splitlines():
        if line.startswith("Load Average:"):
            load_avg = float(line.split(":")[1].split(",")[0])
        f = line.split()
        if len(f) >= 6 and f[0].startswith("BM_") and f[2] in TIME_UNITS:
            counters = {}
            for c in f[6:]:
                k, _, v = c.partition("=")
                m = COUNTER.match(v)
                if m:  # "1.37701k", "23.65k/s" (a rate), "0.00%" (a coefficient of variation)
                    counters[k] = float(m.group(1)) * {"k": 1e3, "M": 1e6, "G": 1e9}.get(m.group(2), 1)
            rows[f[0]] = (float(f[1]) * TIME_UNITS[f[2]], counters)
    return rows, load_avg


def cut_latency():
    """One blade step on the SOFA liver: elements re-estimated, wall, the local update's share, and the
    exact step solve after it (medians of 5)."""
    rows, load_avg = google_benchmark("cutsim_bench.txt")
    out = []
    for label, bench, exact in [("10 elements", "BM_CutBladeStep/10/repeats:5/manual_time_median", None),
                                ("25 elements", "BM_CutBladeStep/25/repeats:5/manual_time_median", None),
                                ("50 elements", "BM_CutBladeStep/50/repeats:5/manual_time_median",
                                 "BM_CutExactDt/0/repeats:5_median"),
                                ("a plane through 91 elements", "BM_CutPlane/repeats:5/manual_time_median",
                                 "BM_CutExactDt/1/repeats:5_median")]:
        wall, c = rows[bench]
        cell = f"{1e3 * wall:.2f} ms"
        out.append([label, f"{c['est_elems']:.0f}", f"**{cell}**" if label == "50 elements" else cell,
                    f"{1e-3 * c['update_us']:.2f} ms", f"{1e3 * rows[exact][0]:.2f} ms" if exact else ""])
    return table(["blade step crossing", "re-estimated", "wall", "of which the update",
                  "exact dt afterwards (Lanczos)"], out) + f"\nLoad average {load_avg:.1f} as the run started.\n"


# ---- bench cutstep: docs/bench/cutstep.json ----


def cutstep():
    """Tables 5.5 and 5.6: the exact step after each cut over the uncut one, per object and method."""
    j = load("cutstep.json")
    rows = []
    for o in j["objects"]:
        for me in o["methods"]:
            cuts = me["cuts"]
            last = cuts[-1]
            n = len(cuts)

            def mean(key):
                return 1e3 * sum(c[key] for c in cuts) / n

            crit = f"{last['critical']} ({100 * last['critical_share']:.1f}%)" if last["critical"] else "0"
            improve = mean("improve_seconds")
            floor = mean("floor_seconds")
            mass = ""
            if "floor" in me["name"]:
                mass = percent(last["added_mass"]) if last["added_mass"] > 0 else "0"
            rows.append([o["name"], me["name"]] + [decimals(c["dt_ratio"], 4) for c in cuts] +
                        [str(last["elements"]), crit, decimals(mean("cut_seconds"), 2),
                         decimals(mean("update_seconds"), 2), decimals(improve, 1) if improve > 0 else "",
                         decimals(floor, 2) if floor > 0 else "", mass,
                         decimals(me["cost"]["wall_per_simulated_second"], 3)])
    return table(["object", "method", "cut 1", "cut 2", "cut 3", "cut 4", "tets", "critical", "cut", "update",
                  "improve", "floor", "mass added", "cost"], rows) + ran_on(j)



LIVER_CUTS_METHODS = [("xfem", "XFEM virtual elements"), ("subdivision", "conforming subdivision"),
                      ("subdivision_improve", "conforming subdivision + improve"), ("remesh", "TetGen remesh")]


def liver_cuts():
    """liver_cuts.json's report `compare`: the exact step after each cut over the uncut one, per method."""
    c = load("liver_cuts.json")["compare"]
    rows = [[label] + [decimals(r, 4) for r in c[key]["dt_ratio"]] for key, label in LIVER_CUTS_METHODS if key in c]
    return table(["method", "cut 1", "cut 2", "cut 3", "cut 4"], rows)


def cutstep_budget():
    """subdivision+improve's budget against its step: the step after cuts 1 and 4, and its improvement's
    time per cut (the median over the four cuts of each cut's median over the runs of a setting)."""
    runs = load("cutstep_budget.json")
    settings = {}
    for j in runs:
        method = j["objects"][0]["methods"][0]["name"]
        settings.setdefault((method, j["problems"], j["free_nodes"]), []).append(j)
    rows = []
    for (method, problems, free), js in settings.items():
        if method.endswith("-full"):
            label = f"unbudgeted (`{method}`)"
        elif problems == 0 and free == 0:
            label = "budgeted (default: 5000 problems, 40 free nodes)"
        else:
            label = f"{problems} problems, {free} free nodes"
        cells = [label]
        for k, o in enumerate(js[0]["objects"]):
            cuts = o["methods"][0]["cuts"]
            per_cut = [statistics.median(j["objects"][k]["methods"][0]["cuts"][c]["improve_seconds"] for j in js)
                       for c in range(len(cuts))]
            cells += [f"{decimals(cuts[0]['dt_ratio'], 4)} / {decimals(cuts[-1]['dt_ratio'], 4)}",
                      decimals(1e3 * statistics.median(per_cut), 1)]
        rows.append(cells)
    names = [o["name"] for o in runs[0]["objects"]]
    header = ["setting"] + [h for n in names for h in (f"{n}: step after cuts 1 / 4", f"{n}: ms per cut")]
    return table(header, rows) + ran_on(*runs)

# ---- bench contact and bench cost per scene: docs/bench/contact.json, cost_SCENE.json ----


def contact_by_points():
    """contact.json's projection runs (no penalty stiffness) by contact points: {points: {tool: run}}."""
    by = {}
    for r in load("contact.json")["runs"]:
        if r["stiffness_fraction"] == 0:
            by.setdefault(r["points"], {})[r["tool"]] = r
    return by


def contact_projection():
    """Projection contact: stage times per step, tool away and pressing, against the contact points."""
    j = load("contact.json")
    rows = []
    for k, (points, r) in enumerate(contact_by_points().items()):
        a, p = r["away"], r["pressing"]
        us = 1e6
        rows.append([f"{points:,}" + (" (vertices only)" if k == 0 else ""),
                     f"{us * a['contact_seconds_per_step']:.1f} / {us * a['elastic_seconds_per_step']:.0f} us "
                     f"({percent(a['contact_seconds_per_step'] / a['elastic_seconds_per_step'], 1)})",
                     f"{us * p['contact_seconds_per_step']:.0f} / {us * p['elastic_seconds_per_step']:.0f} us "
                     f"({p['contact_seconds_per_step'] / p['elastic_seconds_per_step']:.2f})",
                     f"{1e3 * p['max_depth']:.2f} mm", f"{p['final_force']:.2f} N"])
    return table(["contact points", "away: contact / elastic", "pressing: contact / elastic",
                  "pressing: deepest point", "force"], rows) + ran_on(j)


def contact_penalty():
    """The penalty model against its stiffness (a share of the certified limit): depth and force."""
    j = load("contact.json")
    rows = []
    for r in j["runs"]:
        f = r["stiffness_fraction"]
        if f == 0:
            continue
        depth = f"{1e3 * r['max_depth']:.2f} mm" + (" (deeper than pressed)" if r["max_depth"] > j["pressed"] else "")
        rows.append([decimals(f, 2) + (" (its default)" if f == 0.5 else ""), depth, f"{r['final_force']:.2f} N"])
    return table(["k / k_max", "deepest point", "force"], rows)


COST_SCENES = [("probe", "probe.json"), ("demo_mi", "demo_mi.json"), ("demo", "demo.json (MI liver, probe, 2 cuts)"),
               ("blade", "blade.json (with its floor)")]


def contact_scenes():
    """Per scene, the run as given: the contact stage against the elastic step (forces + integrate)."""
    rows = []
    results = [load(f"cost_{name}.json") for name, _ in COST_SCENES]
    for (name, label), j in zip(COST_SCENES, results):
        v = next(v for v in j["variants"] if v["name"] == "as given")
        st = v["stages"]
        elastic = st["forces"] + st["integrate"]
        rows.append([label, f"{st['contact']:.3f} s", f"{elastic:.3f} s", f"**{st['contact'] / elastic:.2f}**"])
    return table(["scene", "contact", "forces + integrate", "contact / (forces + integrate)"], rows) + \
        ran_on(*results)


# ---- bench haptic: docs/bench/haptic.json ----


def haptic():
    """Steps per second of the liver under the probe, per thread count."""
    j = load("haptic.json")
    rows = []
    for r in j["runs"]:
        rows.append([str(r["threads"]), f"{r['steps_per_second']:,.0f}", "yes" if r["haptic_rate"] else "no",
                     f"{100 * r['contact_share']:.0f}%", decimals(r["contact_per_elastic"], 2),
                     decimals(r["real_time_factor"], 3)])
    return table(["threads", "steps/s", "1 kHz", "contact share of the loop", "contact / elastic",
                  "simulated s per wall s"], rows) + ran_on(j)


# ---- bench capture: docs/bench/capture.json ----


def capture():
    """Per scene, each run's wall, physics, capture per frame and its parts, how much the pipeline hid,
    and the CPU per frame; beneath, the ranges the text quotes."""
    j = load("capture.json")
    by = {}
    for r in j["runs"]:
        by.setdefault(r["scene"], []).append(r)
    rows = []
    for scene, runs in by.items():
        def each(f):
            return ", ".join(f(r) for r in runs)

        rows.append([f"{scene} ({runs[0]['frames']} frames)", each(lambda r: decimals(r["wall_s"], 2)),
                     each(lambda r: decimals(r["physics_s"], 2)),
                     each(lambda r: decimals(r["capture_ms_per_frame"], 1)) + " ms",
                     each(lambda r: " / ".join(decimals(r[k], 1) for k in ("draw_ms", "read_ms", "handoff_ms"))),
                     each(lambda r: decimals(r["wall_over_max"], 2)),
                     each(lambda r: f"{r['cpu_ms_per_frame']:.1f} + {r['ffmpeg_cpu_ms_per_frame']:.1f}")])
    what = f"{j['width']}x{j['height']}" + (", HUD" if j["hud"] else "") + (", video" if j["video"] else "") + ", PNGs"
    runs = j["runs"]
    cores = j["machine"]["cores"]
    cpu = [r["cpu_ms_per_frame"] + r["ffmpeg_cpu_ms_per_frame"] for r in runs]
    reached = "Not reached" if min(r["capture_ms_per_frame"] for r in runs) > 1e3 / 60 else "Reached"

    def hundredths(v):
        return decimals(v, 2)

    def whole(v):
        return decimals(v, 0)

    return table([what, "wall [s]", "physics [s]", "(render + encode) / frame",
                  "of which draw / read-back / hand-off [ms]", "wall / max(physics, render + encode)",
                  "CPU / frame, cutsim + ffmpeg [ms]"], rows) + ran_on(j) + (
        f"\n{reached}: 1/60 s a frame. The wall time is {span([r['wall_over_max'] for r in runs], hundredths)} "
        f"times the larger of the physics and the capture (set-up, {span([r['setup_s'] for r in runs], hundredths)} "
        f"s, counts in neither); the capture's CPU, cutsim's and ffmpeg's, is {span(cpu, whole)} ms a frame: on "
        f"{cores} cores about {span([c / cores for c in cpu], whole)} ms a frame at best.\n")


# ---- scripts/bench_runs.py: docs/bench/tetra_heldout.json, liver_hires.json ----


def tetra_heldout():
    """`cutsim tetra` per surface and mesher: the mesh it made, the step quality before and after the
    improvement, its volume and boundary against the surface, and the wall time."""
    j = load("tetra_heldout.json")
    rows = []
    for r in j["runs"]:
        t = r["seconds"]["total"]
        made = "Gmsh" if r["mesher"] == "gmsh" else "TetGen"
        if r["mesher"] == "gmsh":
            made += f" ({r['crease_angle']:g})"
            n = r.get("gmsh_refinements", 0)
            if n:
                made += ", refined " + ("once" if n == 1 else f"{n} times") + " where it left the surface"
            if r.get("improver_creases", 180) < 180:
                made += ", improved again with creases"
        elif r["mesher_option"] == "auto":
            made += " (Gmsh's mesh out of bounds)"
        before = r["step_quality"] * r["dt_before"] / r["dt_after"]
        rows.append([r["surface"], r["mesher_option"], f"{r['size']:g}", made, f"{r['elements']:,}",
                     f"{before:.2f} -> {r['step_quality']:.2f}", f"{100 * r['volume_error']:+.2f}%",
                     f"{100 * r['boundary_distance_rel']:.2f}%", str(r["inverted"]),
                     f"{t:.1f} ({t * 1e4 / r['elements']:.2f})"])
    return table(["surface", "--mesher", "--size", "mesher (crease angle)", "elements", "step quality",
                  "volume", "boundary / diagonal", "inverted", "wall [s] (per 10k elements)"], rows) + ran_on(j)


def liver_hires_sizes():
    """The high-resolution scene at several sizes of object.tetra: the mesh made, the result, and the run's
    times."""
    j = load("liver_hires_sizes.json")
    rows = []
    for r in j["runs"]:
        st, m, t = r["stages"], r["mesh"], r["tetra"]
        result = r["status"] if r["status"] == "ok" else f"{r['status'].split(':')[0]} at t = {r['sim_time']:.3f} s"
        inv = r.get("inverted", {})
        rows.append([r["value"], f"{m['elements']:,} ({m['elements_final']:,})", f"{t['step_quality']:.2f}",
                     f"{1e3 * t['dt_after']:.3f}", f"{result}, {r['pieces']} pieces", f"{r['steps']:,}",
                     f"{r['wall_time']:.1f}", f"{t['seconds']:.1f}",
                     " / ".join(f"{st[k]:.1f}" for k in ("forces", "integrate", "contact", "cut", "timestep")),
                     f"{inv.get('steps', 0)} ({inv.get('max_elements', 0)})"])
    return table(["object.tetra.size", "tets (after the cuts)", "step quality", "exact step [ms]", "result",
                  "steps", "wall [s]", "meshing [s]", "forces / integrate / contact / cut / time step [s]",
                  "steps with an inverted element (most at once)"], rows) + ran_on(j)


def blade_scale():
    """blade.json's stroke per object: elements, result and pieces, the stroke's blade steps and their
    latency, the cut and time-step stages and the contact stage against the elastic step, and the wall."""
    j = load("blade_scale.json")
    rows = []
    for r in j["runs"]:
        st, m = r["stages"], r["mesh"]
        fi = st["forces"] + st["integrate"]
        result = r["status"] if r["status"] == "ok" else f"{r['status'].split(':')[0]} at t = {r['sim_time']:.3f} s"
        pieces = ", ".join(f"{1e6 * v:.1f}" if v < 1e-6 else f"{1e6 * v:.0f}"
                           for v in sorted(r.get("piece_volumes", []), reverse=True))
        strokes = r.get("strokes", [])
        steps = sum(k["blade_steps"] for k in strokes)
        lat = strokes[0]["latency"] if strokes else None
        quality = f"{r['tetra']['step_quality']:.2f}" if "tetra" in r else ""
        rows.append([r["object"], f"{m['elements']:,} / {m['elements_final']:,}", quality, result, pieces,
                     f"{steps:,}", f"{ms(lat['median'])} / {ms(lat['p99'])} / {ms(lat['max'])}" if lat else "",
                     f"{st['cut']:.1f} / {st['timestep']:.1f}", f"{(st['cut'] + st['timestep']) / fi:.2f}",
                     f"{st['contact'] / fi:.2f}", f"{r['kinetic_end']:.2g}" if r.get("kinetic_end") is not None else "",
                     f"{r['wall_time']:.0f}"])
    return table(["object", "elements at load / at the end", "step quality", "result", "pieces [cm^3]",
                  "blade steps", "latency median / p99 / max [ms]", "cut / time step [s]",
                  "(cut + time step) / (forces + integrate)", "contact / (forces + integrate)",
                  "kinetic energy at the end [J]", "wall [s]"], rows) + ran_on(j)


RUN_STAGES = [("forces", "forces"), ("integrate", "integrate"), ("contact", "contact"), ("cut", "cut"),
              ("timestep", "time step"), ("render", "render"), ("encode", "encode")]


def liver_hires():
    """The high-resolution scene's run: its result and pieces, elements at load and at the end, wall time, and
    stages."""
    j = load("liver_hires.json")
    st = j["stages"]
    result = j["status"] if j["status"] == "ok" else f"{j['status']} at t = {j['sim_time']:.3f} s"
    pieces = ", ".join(f"{1e6 * v:.0f}" for v in sorted(j["piece_volumes"], reverse=True))
    return table(["scene", "result", "pieces [cm^3]", "elements at load / at the end", "frames",
                  f"wall [s] for {j['sim_time']:.1f} s", "per simulated second [s]",
                  " / ".join(label for _, label in RUN_STAGES) + " [s]"],
                 [[f"{j['name']}.json", result, pieces,
                   f"{j['mesh']['elements']:,} / {j['mesh']['elements_final']:,}", str(j["frames"]),
                   decimals(j["wall_time"], 1), f"{j['wall_time'] / j['sim_time']:.0f}",
                   " / ".join(decimals(st[k], 1) for k, _ in RUN_STAGES)]]) + ran_on(j)


# ---- bench threads: docs/bench/threads.json, threads_liver.json ----


THREADS_LOADS = [("idle", "as found"), ("busy", "a loop on the other core")]


def threads_rows(j, key, ratio):
    """Per load of a bench threads result: key's value per round on 1 and 2 threads and on the
    measured count (with the count each run ended on), and with ratio the measured over 1 thread."""
    by = {}
    for r in sorted(j["runs"], key=lambda r: r["round"]):
        by.setdefault((r["load"], r["threads"]), []).append((r[key], r["threads_chosen"]))
    rows = []
    for kind, label in THREADS_LOADS:
        if (kind, 1) not in by:
            continue
        one, choice = by[(kind, 1)], by.get((kind, 0), [])
        cells = [label, ", ".join(decimals(v, 2) for v, _ in one),
                 ", ".join(decimals(v, 2) for v, _ in by.get((kind, 2), [])),
                 ", ".join(f"{v:.2f} ({c})" for v, c in choice)]
        if ratio:
            cells.append(", ".join(decimals(v / w, 2) for (v, _), (w, _) in zip(choice, one)))
        rows.append(cells)
    return rows


def threads_box():
    """bar_sag.json as a 10,368-tet box: seconds in the steps on 1 and 2 threads and the measured
    choice, per round, as found and with a loop on the other core."""
    j = load("threads.json")
    return table(["machine", "1 thread", "2 threads", "measured choice (threads it ended on)"],
                 threads_rows(j, "step_seconds", False)) + ran_on(j)


def threads_liver():
    """The improved 40k-tet liver under probe.json's probe: wall seconds of the whole run, the same."""
    j = load("threads_liver.json")
    return table(["machine", "1 thread", "2 threads", "measured choice (`--threads 0`; threads it ended on)",
                  "choice / 1 thread"], threads_rows(j, "wall_seconds", True)) + ran_on(j)


# ---- scripts/bench_python.py: docs/bench/python_step.txt ----

PYTHON_SIDES = [("cli", "`cutsim run`"), ("python sim.step(1000)", "`sim.step(1000)`"),
                ("python loop", "Python loop: `sim.step()`, `sim.tool_force(0)`")]


def python_step():
    """Each side's median per run of the script (one value when all agree to 0.1 ms) and its
    difference from the CLI's, over the runs the file holds; their loads beneath."""
    medians, over, loads = {}, {}, []
    for line in (DATA / "python_step.txt").read_text(encoding="utf-8").splitlines():
        if "load average:" in line:
            loads.append(float(line.split("load average:")[1].split(",")[0]))
        for key, _ in PYTHON_SIDES:
            if line.strip().startswith(key):
                f = line.split("ms")[0].split()[-1], line.split("ms")[1].split()[0]
                medians.setdefault(key, []).append(float(f[0]))
                over.setdefault(key, []).append(f[1])

    rows = []
    for key, label in PYTHON_SIDES:
        pct = sorted(over[key], key=lambda v: float(v.rstrip("%")))
        rows.append([label, span(medians[key], tenths),
                     "" if key == "cli" else (pct[0] if pct[0] == pct[-1] else f"{pct[0]} to {pct[-1]}")])
    return table(["side", "median [ms]", "over the CLI"], rows) + \
        f"\n{len(loads)} runs, load average {span(loads, tenths)} as they started.\n"


# ---- bench cost: docs/bench/cost.json ----


def cost():
    """Per-stage seconds of bar_sag.json, as given and without each optional part."""
    j = load("cost.json")
    variants = j["variants"]
    rows = [[v["name"]] + [decimals(x, 3) for x in (v["wall_time"], v["stages"]["forces"], v["stages"]["integrate"],
                                                     v["stages"]["timestep"])] for v in variants]
    return table([f"variant (40x4x4 bar, {variants[0]['steps']} steps)", "wall [s]", "forces", "integrate",
                  "timestep"], rows) + ran_on(j)


# ---- the summary at the top of the page: its numbers from the results above ----


def x_span(values, n=0):
    """A range of ratios: "13-21x", or "2.2x" when its ends agree."""
    return span(values, lambda v: decimals(v, n)) + "x"


def summary_step():
    rotated = [r["ratio_cutsim_double_to_bullet"] for r in load("bullet_step.json")["runs"]]
    rest = [r["ratio_cutsim_double_to_bullet"] for r in load("bullet_step_unrotated.json")["runs"]]
    return (f"**{x_span(rotated)}** Bullet's explicit deformable solver on the same meshes, one thread "
            f"({x_span(rest)} from the rest shape)")


def summary_accuracy():
    paired = load("accuracy_1pct_paired.json")
    implicit = paired["summary"]["cantilever_frequency"]["paired_implicit"]
    c = next(p for p in paired["paired"] if p["implicit"] == implicit)
    ratio = {" single " in e["config"]: e["ratio"] for e in c["explicit"]}
    ldlt = load("accuracy_1pct.json")["summary"]["cantilever_frequency"]["speedup_at_1pct_projected"]
    return (f"at 1% tip-frequency error, **{ratio[True]:.1f}x** cheaper than backward Euler with CG "
            f"(single-precision forces; {ratio[False]:.1f}x double), ~{5 * round(ldlt / 5)}x than backward Euler "
            "with LDL^T")


def summary_scale():
    j = load("scale.json")
    one = [r for r in j["runs"] if r["threads"] == 1 and "stages" in r]
    fits = {(f["mesh"], f["scene"]): f["exponents"] for f in j["exponents"] if f["threads"] == 1}

    def exps(scene, stage):
        return span([fits[(k, scene)][stage] for k, _ in SCALE_KINDS], lambda v: decimals(v, 1))

    largest = max(r["elements"] for r in one if r["mesh"] == "tetgen")
    blade = next(r for r in one if r["mesh"] == "tetgen" and r["elements"] == largest and r["scene"] == "blade")

    def kb(kind):
        r = max((r for r in one if r["mesh"] == kind and r["scene"] == "sag"), key=lambda r: r["elements"])
        return f"{r['bytes_per_element'] / 1e3:.1f} kB"

    def k(n):
        return f"{n / 1e3:.1f}k" if n < 1e4 else f"{n / 1e3:.0f}k"

    return (f"per step, on one thread, from {k(min(r['elements'] for r in one))} to {k(largest)} elements: the elastic "
            f"step ~ n^{exps('sag', 'step')}, a blade step's cut stage **~ n^{fits[('tetgen', 'blade')]['cut']:.2f}** "
            f"({1e3 * blade['stages']['cut']:.0f} ms at {k(largest)} tets), the four plane cuts' exact step after "
            f"them ~ n^{exps('cuts', 'timestep')}; {kb('tetgen')} per TetGen element, {kb('mi')} per MI element")


def summary_cut():
    rows, _ = google_benchmark("cutsim_bench.txt")
    wall = rows["BM_CutBladeStep/50/repeats:5/manual_time_median"][0]
    j = load("liver_cuts.json")
    return (f"a blade step crossing 50 liver elements, with the local update of the time-step analysis: "
            f"**{1e3 * wall:.1f} ms**; after the thesis's four liver cuts the exact step is still "
            f"{j['dt_final']['exact'] / j['dt_initial']['exact']:.3f} of the uncut one")


def summary_improve():
    meshes = load("improve.json")["meshes"]

    def gains(method):
        return [m["methods"][method]["gain"] for m in meshes if "gain" in m["methods"].get(method, {})]

    liver = next(m for m in meshes if m["mesh"] == "liver")
    speed = load("improve_speed.json")
    per10k = {}
    for r in speed["runs"]:
        if r["threads"] == 2 and r["load"] == "idle":
            per10k.setdefault(r["mesh"], []).append(r["seconds"] * 1e4 / r["tets"])
    per10k = [statistics.median(v) for v in per10k.values()]
    tetgen = "leaves it unchanged" if all(f"{g:.2f}" == "1.00" for g in gains("tetgen -rO10/7")) else \
        f"gains {x_span(gains('tetgen -rO10/7'), 1)}"
    return (f"the exact step of the data meshes **{x_span(gains('cutsim'), 1)}** larger in "
            f"{span(per10k, lambda v: decimals(v, 2))} s per 10,000 tets on 2 cores idle (SOFA liver "
            f"{1e3 * liver['dt_exact']:.3f} -> {1e3 * liver['methods']['cutsim']['dt_exact']:.3f} ms, thesis 0.713 in "
            f"minutes); TetGen's optimiser {tetgen}, Gmsh's gains {x_span(gains('gmsh'), 1)}, CGAL's remesher "
            f"{x_span(gains('cgal remesh'), 1)} with other element counts")


def summary_cutstep():
    liver = next(o for o in load("cutstep.json")["objects"] if o["name"] == "liver")
    last = {m["name"]: m["cuts"][-1] for m in liver["methods"]}
    budget = load("cutstep_budget.json")

    def setting(method, problems):
        """A budget setting's liver: the step after cut 4 (the same in each run) and the median
        improvement time per cut, as the budget table gives them."""
        js = [j for j in budget if j["objects"][0]["methods"][0]["name"] == method and j["problems"] == problems]
        o = next(k for k, o in enumerate(js[0]["objects"]) if o["name"] == "liver")
        cuts = js[0]["objects"][o]["methods"][0]["cuts"]
        per_cut = [statistics.median(j["objects"][o]["methods"][0]["cuts"][c]["improve_seconds"] for j in js)
                   for c in range(len(cuts))]
        return f"{cuts[-1]['dt_ratio']:.2f} in {1e3 * statistics.median(per_cut):.0f} ms"

    problems = sorted({j["problems"] for j in budget if j["problems"]})
    loads = [x for j in budget for x in (j["machine"]["load_average"][0], j["machine"]["load_average_end"][0])]
    return (f"XFEM keeps **{last['xfem']['dt_ratio']:.2f}** of the liver's uncut exact step "
            f"({last['xfem+floor']['dt_ratio']:.3f} with the floor, {percent(last['xfem+floor']['added_mass'])} mass "
            f"added; {last['xfem+hybrid']['dt_ratio']:.2f} with the hybrid), conforming subdivision "
            f"{last['subdivision']['dt_ratio']:.2f}, subdivision with a local improvement "
            f"{setting('subdivision+improve', 0)} a cut ({setting('subdivision+improve-full', 0)} at the full setting, "
            f"{setting('subdivision+improve', problems[-1])} with four times the budget; load {min(loads):.1f})")


def summary_stability():
    j = load("stability.json")
    plain = [s["largest_stable_fraction"] for s in j["sweeps"] if s["scheme"] == "plain"] + \
        [s["largest_stable_fraction"] for s in j["after_cuts"]]
    return f"plain explicit schemes are stable to **{min(plain):.3f}** of the exact limit, before and after cuts"


def summary_random_cuts():
    j = load("random_cuts_500.json")
    hybrid = [r for r in j["runs"] if r["floor"] == "hybrid"]
    ok = all(r["failures"] == 0 and r["inverted_runs"] == 0 for r in hybrid)
    mass = percent(max(r["max_added_mass"] for r in hybrid))
    return (f"with the floor ({j['step_floor']:g} of the uncut step) and matching first, {j['sequences']} random "
            f"sequences hold it on the liver and a bar for at most **{mass}** of the mass" +
            (", no blow-up, no inverted element" if ok else ""))


def summary_contact():
    scenes = {}
    for name, _ in COST_SCENES:
        st = next(v for v in load(f"cost_{name}.json")["variants"] if v["name"] == "as given")["stages"]
        scenes[name] = st["contact"] / (st["forces"] + st["integrate"])
    away = [r["away"] for r in contact_by_points().values()]
    away = [a["contact_seconds_per_step"] / a["elastic_seconds_per_step"] for a in away]
    h = load("haptic.json")
    rate = {r["threads"]: r["steps_per_second"] for r in h["runs"]}
    return (f"**{span([v for k, v in scenes.items() if k != 'blade'], lambda v: decimals(v, 2))}** of the elastic "
            f"step on the probe and demo scenes, {scenes['blade']:.2f} on blade.json; a tool away "
            f"{span(away, lambda v: decimals(100 * v, 1))}%; a {h['runs'][0]['tets'] / 1e3:.0f}k-tet liver under a "
            f"probe at **{rate[1]:,.0f}** steps/s on one thread, {rate[2]:,.0f} on two "
            f"(load {h['machine']['load_average'][0]:.0f})")


SUMMARY = [("step throughput against Bullet", summary_step,
            "[Step](#step-throughput-cutsim-bench-step-and-cutsim_bullet_bench)"),
           ("explicit against the implicit reference", summary_accuracy,
            "[Accuracy](#accuracy-against-cost-cutsim-bench-accuracy)"),
           ("how cost grows with the mesh", summary_scale, "[How cost grows](#how-cost-grows-cutsim-bench-scale)"),
           ("what a cut costs", summary_cut, "[Cutting](#cutting-latency-and-the-step-after-cuts)"),
           ("how much step a mesh improvement buys", summary_improve,
            "[Improvement](#mesh-improvement-cutsim-bench-improve-table-51)"),
           ("the step through four cuts", summary_cutstep,
            "[Step through cuts](#step-through-cuts-thesis-tables-55-and-56-cutsim-bench-cutstep)"),
           ("how close to the limit it steps", summary_stability, "[Stability](#stability-cutsim-bench-stability)"),
           ("the step through random cuts", summary_random_cuts, "[Stability](#stability-cutsim-bench-stability)"),
           ("what contact costs", summary_contact, "[Contact](#contact)")]


def summary():
    """The page's summary: per question the answer its section's results give."""
    return table(["question", "answer", "section"], [[q, f(), link] for q, f, link in SUMMARY])


TABLES = {
    "summary": summary,
    "scale-step": scale_step,
    "scale-exponents": scale_exponents,
    "accuracy-paired": accuracy_paired,
    "accuracy-notch": accuracy_notch,
    "mi-bar": mi_bar,
    "step-bullet": step_bullet,
    "step-threads": step_threads,
    "stability-sweeps": stability_sweeps,
    "stability-after-cuts": stability_after_cuts,
    "stability-floor": stability_floor,
    "stability-500": stability_500,
    "dt-table43": dt_table43,
    "improve": improve_table,
    "improve-time": improve_time,
    "improve-speed": improve_speed,
    "cut-latency": cut_latency,
    "liver-cuts": liver_cuts,
    "cutstep": cutstep,
    "cutstep-budget": cutstep_budget,
    "contact-projection": contact_projection,
    "contact-penalty": contact_penalty,
    "contact-scenes": contact_scenes,
    "haptic": haptic,
    "cost": cost,
    "python-step": python_step,
    "capture": capture,
    "tetra-heldout": tetra_heldout,
    "liver-hires": liver_hires,
    "blade-scale": blade_scale,
    "liver-hires-sizes": liver_hires_sizes,
    "threads-box": threads_box,
    "threads-liver": threads_liver,
}


def generate(text):
    """The page with every generated table rewritten; a name without a table is an error."""

    def replace(m):
        name = m.group(2)
        if name not in TABLES:
            raise SystemExit(f"BENCHMARKS.md: no table named '{name}' (known: {', '.join(TABLES)})")
        return m.group(1) + TABLES[name]() + m.group(4)

    opened = text.count("<!-- generated: ")
    if opened != len(BLOCK.findall(text)) or opened != text.count("<!-- end generated -->"):
        raise SystemExit("BENCHMARKS.md: a '<!-- generated: NAME -->' without its '<!-- end generated -->'")
    return BLOCK.sub(replace, text)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--check", action="store_true", help="exit 1 when BENCHMARKS.md differs from the data")
    args = ap.parse_args()
    text = PAGE.read_text(encoding="utf-8")
    new = generate(text)
    if args.check:
        if new != text:
            sys.stdout.writelines(difflib.unified_diff(text.splitlines(True), new.splitlines(True),
                                                       "BENCHMARKS.md", "generated from docs/bench"))
            print("BENCHMARKS.md's tables differ from docs/bench: run scripts/bench_tables.py", file=sys.stderr)
            return 1
        return 0
    if new != text:
        PAGE.write_text(new, encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
