"""A haptic loop cutting the liver with its toughness: steps assets/scenes/blade_toughness.json
(material.toughness 200 J/m^2, porcine liver, blade) and reads the blade's force after every step,
as a 1 kHz haptic loop would render it; prints the force and the cutting phase (pressing, then
rupture and cutting) every millisecond of the stroke, and plots them (haptic_cut.png). Run from
the checkout after building:

    PYTHONPATH=build/python python3 examples/haptic_cut.py [--toughness 200] [--out haptic_cut.png]
"""
import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # no display needed
import matplotlib.pyplot as plt
import numpy as np

import cutsim

SCENE = Path(__file__).resolve().parents[1] / "assets" / "scenes" / "blade_toughness.json"


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--toughness", type=float, default=200.0, help="material.toughness [J/m^2]")
    ap.add_argument("--until", type=float, default=0.6, help="simulated seconds to run")
    ap.add_argument("--out", default="haptic_cut.png")
    args = ap.parse_args()

    sim = cutsim.Simulation(str(SCENE), set=[f"material.toughness={args.toughness}"], threads=1)
    # the force a device renders each millisecond: the mean of the steps' forces over it
    times, forces, phases = [], [], []
    acc, n, next_sample = np.zeros(3), 0, 0.001
    while sim.time < args.until and not sim.finished:
        sim.step()
        acc += sim.tool_force(0)
        n += 1
        if sim.time >= next_sample:
            f = acc / n
            times.append(sim.time)
            forces.append(np.linalg.norm(f))
            phases.append(sim.cut_phase())
            acc, n, next_sample = np.zeros(3), 0, next_sample + 0.001
    sim.finish()
    last = None
    for t, f, p in zip(times, forces, phases):
        if p != last or round(t * 1000) % 20 == 0:
            print(f"t = {t:.3f} s  |F| = {f:7.3f} N  {p}")
        last = p
    rep = sim.report()
    tough = rep["blade"].get("toughness", {})
    print(f"status {rep['status']}: peak {tough.get('peak_force', 0):.2f} N, cut area {tough.get('cut_area', 0):.3g} m^2")

    fig, ax = plt.subplots(figsize=(7, 3.5))
    ax.plot(times, forces, lw=1)
    cutting = [t for t, p in zip(times, phases) if p == "cutting"]
    if cutting:
        ax.axvspan(min(cutting), max(cutting), color="0.9", label="cutting")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("blade force [N]")
    ax.set_title(f"blade_toughness.json, toughness {args.toughness:g} J/m$^2$")
    ax.legend(loc="upper left")
    fig.tight_layout()
    fig.savefig(args.out, dpi=120)
    print("wrote", args.out)


if __name__ == "__main__":
    main()
