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
import re
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


def decimals(v, n):
    return f"{v:.{n}f}"


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


TABLES = {
    "scale-step": scale_step,
    "scale-exponents": scale_exponents,
    "accuracy-paired": accuracy_paired,
    "mi-bar": mi_bar,
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
