"""Presses the probe of assets/scenes/probe.json to a range of depths and plots the reaction force
against depth (force_vs_depth.png). Run from the checkout after building:

    PYTHONPATH=build/python python3 examples/probe_depth_sweep.py [--out force_vs_depth.png]
"""
import argparse
import json
from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # no display needed
import matplotlib.pyplot as plt
import numpy as np

import cutsim

SCENE = Path(__file__).resolve().parents[1] / "assets" / "scenes" / "probe.json"


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="force_vs_depth.png")
    ap.add_argument("--depths", type=int, default=12, help="depths between the surface and 12 mm")
    ap.add_argument("--settle", type=float, default=0.05, help="seconds held at each depth before the force is read")
    args = ap.parse_args()

    scene = json.loads(SCENE.read_text())
    radius = scene["tools"][0]["radius"]
    sim = cutsim.Simulation(scene, set=["duration=100"], path=str(SCENE))
    start = sim.tool_position(0)
    # depth below the undeformed surface: the top of the nodes under the probe
    x = sim.rest_positions
    under = np.hypot(x[:, 0] - start[0], x[:, 2] - start[2]) < radius
    touch = start[1] - radius - x[under, 1].max()
    steps = int(args.settle / sim.dt) + 1
    depths, forces = [], []
    for d in np.linspace(0.0, 0.012, args.depths + 1):
        # one quasi-static hold a depth, deeper each time
        sim.set_tool(0, start - [0, touch + d, 0])
        sim.step(steps)
        depths.append(1e3 * d)
        forces.append(np.linalg.norm(sim.tool_force(0)))
        print(f"probe {depths[-1]:5.1f} mm deep: |F| = {forces[-1]:.4f} N")

    fig, ax = plt.subplots(figsize=(5, 3.5), dpi=120)
    ax.plot(depths, forces, "o-")
    ax.set_xlabel("probe depth below the undeformed surface [mm]")
    ax.set_ylabel("reaction force |F| [N]")
    ax.set_title(f"sphere r = {1e3 * radius:g} mm into the liver (E = {scene['material']['E']:g} Pa)")
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(args.out)
    print("->", args.out)


if __name__ == "__main__":
    main()
