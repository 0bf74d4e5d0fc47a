"""Runs the blade scene from Python and records a video of it: every frame is rendered offscreen
into numpy and piped to ffmpeg (blade.mp4). Run from the checkout after building:

    PYTHONPATH=build/python python3 examples/record_video.py [--out blade.mp4] [--fps 30]
"""
import argparse
import subprocess
from pathlib import Path

import cutsim

SCENE = Path(__file__).resolve().parents[1] / "assets" / "scenes" / "blade.json"


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="blade.mp4")
    ap.add_argument("--fps", type=float, default=30)
    ap.add_argument("--width", type=int, default=640)
    ap.add_argument("--height", type=int, default=360)
    args = ap.parse_args()

    sim = cutsim.Simulation(str(SCENE))
    ffmpeg = subprocess.Popen(
        ["ffmpeg", "-loglevel", "error", "-y", "-f", "rawvideo", "-pix_fmt", "rgb24",
         "-s", f"{args.width}x{args.height}", "-r", str(args.fps), "-i", "-",
         "-c:v", "libx264", "-pix_fmt", "yuv420p", args.out],
        stdin=subprocess.PIPE)
    frames = 0
    while not sim.finished:
        ffmpeg.stdin.write(sim.render(args.width, args.height).tobytes())
        frames += 1
        sim.advance(min(sim.duration, frames / args.fps))
    ffmpeg.stdin.close()
    if ffmpeg.wait() != 0:
        raise SystemExit("ffmpeg failed")
    print(f"{frames} frames, {sim.cuts} cuts, {sim.steps} steps -> {args.out}")


if __name__ == "__main__":
    main()
