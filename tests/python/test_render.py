# A frame rendered offscreen into numpy: the same picture as the CLI's first frame.
import numpy as np
import pytest

import cutsim
from conftest import SCENES, run_cli

PROBE = str(SCENES / "probe.json")
SMALL = ["capture.width=160", "capture.height=120", "capture.hud=false", "capture.video=false", "duration=0.02"]

if not hasattr(cutsim.Simulation, "render"):
    pytest.skip("this build has no renderer", allow_module_level=True)


def test_frame_is_an_rgb_image_like_the_cli(tmp_path):
    mpimg = pytest.importorskip("matplotlib.image")
    rc, err, _ = run_cli(["run", PROBE, "--quiet", "--threads", "1", *[a for s in SMALL for a in ("--set", s)]], tmp_path)
    assert rc == 0, err
    cli = (mpimg.imread(str(tmp_path / "frames" / "frame_000000.png"))[:, :, :3] * 255).round().astype(np.uint8)
    sim = cutsim.Simulation(PROBE, set=SMALL, threads=1)
    img = sim.render()
    assert img.shape == (120, 160, 3) and img.dtype == np.uint8
    assert img.flags.c_contiguous
    background = img[0, 0]
    assert (np.abs(img.astype(int) - background).sum(axis=2) > 30).mean() > 0.05  # the liver is in view
    diff = np.abs(img.astype(int) - cli.astype(int)).max(axis=2)
    assert (diff > 2).mean() < 0.001, f"{(diff > 2).mean():.4f} of the pixels differ from the CLI's frame"


def test_frames_follow_the_state_and_the_cut():
    sim = cutsim.Simulation(PROBE, set=SMALL[:4] + ["duration=0.3"], threads=1)
    a = sim.render(96, 64)
    assert a.shape == (64, 96, 3)
    sim.cut_plane([-0.03, 0.06, 0.0], [1, 0, 0])
    b = sim.render(96, 64)
    assert b.shape == a.shape and not np.array_equal(a, b)  # the cut faces are drawn
