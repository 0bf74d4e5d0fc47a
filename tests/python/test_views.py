# The views of the state across cuts: a view taken before a cut keeps reading the state of just
# before it (its memory stays alive, frozen there), the property taken again reads the new state;
# set_tool with an orientation.
import os
import shutil
import subprocess
import sys
import textwrap

import numpy as np
import pytest

import cutsim
from conftest import SCENES

BAR = str(SCENES / "bar_sag.json")
BLADE = str(SCENES / "blade.json")
LIVER_CUTS = str(SCENES / "liver_cuts.json")
PROBE = str(SCENES / "probe.json")


def address(a):
    return a.__array_interface__["data"][0]


def views(sim):
    return {
        "positions": sim.positions,
        "velocities": sim.velocities,
        "rest_positions": sim.rest_positions,
        "element_steps": sim.element_steps,
    }


def churn(arrays):
    """Allocates and fills arrays of the views' sizes many times: freed memory of theirs would be
    reused and overwritten by these (or unmapped, and reading it would crash)."""
    keep = []
    for _ in range(20):
        for a in arrays:
            keep.append(np.full(a.shape, -7.0e7))
            keep.append(np.random.default_rng(1).random(a.size))
        if len(keep) > 40:
            keep = keep[-20:]
    return keep


def assert_frozen(before, saved):
    for k, a in before.items():
        assert np.array_equal(a, saved[k]), k
        assert float(np.abs(a).sum()) == float(np.abs(saved[k]).sum()), k  # every element read


def test_a_view_taken_before_a_cut_keeps_the_pre_cut_values():
    sim = cutsim.Simulation(BAR, set=["duration=0.3"], threads=1)
    sim.step(50)
    n0, e0 = sim.nodes, sim.elements
    before = views(sim)
    saved = {k: a.copy() for k, a in before.items()}
    r = sim.cut_plane([0.51, 0.05, 0.0], [1, 0, 0])
    assert r["new_nodes"] > 0 and sim.nodes == n0 + r["new_nodes"] and sim.elements > e0
    after = views(sim)
    for k in ("positions", "velocities", "rest_positions"):
        assert before[k].shape == (n0, 3) and after[k].shape == (sim.nodes, 3)
        assert address(before[k]) != address(after[k])
        # the old nodes keep their values across the cut
        assert np.array_equal(after[k][:n0], saved[k])
    assert before["element_steps"].shape == (e0,) and after["element_steps"].shape == (sim.elements,)
    keep = churn(list(before.values()))
    assert_frozen(before, saved)
    sim.step(50)
    keep += churn(list(before.values()))
    assert_frozen(before, saved)  # the steps move the new arrays, not the retired ones
    x = sim.positions
    assert not np.array_equal(x[:n0], saved["positions"])
    assert np.array_equal(x, after["positions"])  # a view of the new state follows the steps
    del sim, after, x
    assert_frozen(before, saved)  # the retired memory lives as long as its views


def test_views_of_the_current_arrays_are_shared_and_not_copied():
    sim = cutsim.Simulation(BAR, set=["duration=0.3"], threads=1)
    a, b = sim.positions, sim.positions
    assert address(a) == address(b) and not a.flags.writeable and not a.flags.owndata
    sim.step(5)
    assert address(sim.positions) == address(a)  # steps do not move the arrays
    s = a[:, 2]  # a slice keeps its view's memory alive
    saved = s.copy()
    del a, b
    sim.cut_plane([0.51, 0.05, 0.0], [1, 0, 0])
    churn([s])
    assert np.array_equal(s, saved)
    # no view: a cut moves nothing, taking the property again is the new state
    y = sim.positions
    del y, s
    sim.cut_plane([0.31, 0.05, 0.0], [1, 0, 0])
    assert sim.positions.shape == (sim.nodes, 3) and sim.cuts == 2


def test_a_scripted_cut_ahead_of_its_time():
    sim = cutsim.Simulation(LIVER_CUTS, set=["duration=0.3", "cutting.compare=[]"], threads=1)
    before = views(sim)
    saved = {k: a.copy() for k, a in before.items()}
    n0 = sim.nodes
    assert sim.cut_next_scripted()  # cuts[0] now
    assert sim.nodes > n0
    churn(list(before.values()))
    assert_frozen(before, saved)


def test_a_scripted_cut_in_a_step():
    sim = cutsim.Simulation(LIVER_CUTS, set=["duration=0.25", "cutting.compare=[]"], threads=1)
    sim.step(5)
    x, v = sim.positions, sim.velocities
    n0 = sim.nodes
    while sim.cuts == 0:  # cuts[0] at 0.2 s is made in the cut stage of a step
        xs, vs = x.copy(), v.copy()
        assert sim.step() == 1
    assert sim.nodes > n0 and sim.positions.shape == (sim.nodes, 3)
    churn([x, v])
    # the cut stage comes before the step's integration: the views stay at the step's start
    assert np.array_equal(x, xs) and np.array_equal(v, vs)
    sim.step(10)
    assert np.array_equal(x, xs) and np.array_equal(v, vs)


def test_a_blade_sweep_in_a_step():
    sim = cutsim.Simulation(BLADE, set=["duration=0.4"], threads=1)
    x, v = sim.positions, sim.velocities
    n0 = sim.nodes
    while sim.nodes == n0 and not sim.finished:
        xs, vs = x.copy(), v.copy()
        sim.step()
    assert sim.nodes > n0, "the blade did not cut"
    churn([x, v])
    assert x.shape == (n0, 3) and np.array_equal(x, xs) and np.array_equal(v, vs)
    sim.step(20)
    churn([x, v])
    assert np.array_equal(x, xs) and np.array_equal(v, vs)
    assert sim.positions.shape == (sim.nodes, 3)


VALGRIND_SCRIPT = textwrap.dedent(
    """
    import numpy as np, cutsim
    sim = cutsim.Simulation(%r, set=["duration=0.3"], threads=1)
    sim.step(20)
    x, v, es = sim.positions, sim.velocities, sim.element_steps
    xs = x.copy()
    sim.cut_plane([0.51, 0.05, 0.0], [1, 0, 0])
    sim.step(5)
    total = float(x.sum() + v.sum() + es.sum())
    assert np.array_equal(x, xs)
    print("ok", total)
    """
)


@pytest.mark.skipif(shutil.which("valgrind") is None, reason="no valgrind")
def test_no_read_of_freed_memory_under_valgrind(tmp_path):
    script = tmp_path / "views.py"
    script.write_text(VALGRIND_SCRIPT % BAR)
    env = dict(os.environ, PYTHONMALLOC="malloc")
    p = subprocess.run(
        ["valgrind", "--tool=memcheck", "--error-limit=no", sys.executable, str(script)],
        capture_output=True,
        text=True,
        env=env,
        timeout=280,
    )
    if "unhandled instruction" in p.stderr:  # -march=native (AVX-512): configure with -DCUTSIM_ARCH=portable
        pytest.skip("valgrind cannot run this build's instructions (CUTSIM_ARCH=native)")
    assert p.returncode == 0, p.stderr[-4000:]
    assert "ok " in p.stdout
    bad = [l for l in p.stderr.splitlines() if "Invalid read" in l or "Invalid write" in l]
    assert not bad, p.stderr[-6000:]


CAPSULE_PROBE = {
    "name": "rod",
    "kind": "capsule",
    "radius": 0.004,
    "length": 0.06,
    "keyframes": [{"time": 0.0, "position": [0.0, 0.2, 0.008]}],
}


def rod_force(orientation):
    # penalty contact: the force of a rod teleported into the tissue is its depth times k
    sim = cutsim.Simulation(PROBE, set=["duration=0.2", "contact.model=penalty", "tools=[%s]" % str(CAPSULE_PROBE).replace("'", '"')], threads=1)
    sim.set_tool(0, [0.0, 0.128, 0.008], orientation)
    sim.step(int(0.02 / sim.dt) + 1)
    return sim, np.linalg.norm(sim.tool_force(0))


def test_set_tool_with_an_orientation():
    flat, f_flat = rod_force(None)  # the rod's axis (local z) lies level on the liver
    assert np.allclose(flat.tool_orientation(0), [1, 0, 0, 0])
    c, s = np.cos(np.pi / 4), np.sin(np.pi / 4)
    up, f_up = rod_force([3 * c, 3 * s, 0, 0])  # a quarter turn about x, not normalised: upright
    assert np.allclose(up.tool_orientation(0), [c, s, 0, 0])
    assert np.allclose(up.tool_position(0), [0.0, 0.128, 0.008])
    assert f_flat > 0 and f_up > 0
    assert abs(f_up - f_flat) > 0.2 * max(f_up, f_flat)  # level: its side presses; upright: its cap
    # the orientation holds until set again; position-only keeps it
    up.set_tool(0, [0.0, 0.135, 0.008])
    up.step(2)
    assert np.allclose(up.tool_orientation(0), [c, s, 0, 0])
    for bad in ([0, 0, 0, 0], [np.nan, 0, 0, 1], [1, 0, 0], [[1, 0], [0, 1]]):
        with pytest.raises(cutsim.InputError):
            up.set_tool(0, [0.0, 0.135, 0.008], bad)
    with pytest.raises(cutsim.InputError):
        up.set_tool(0, [0.0, np.inf, 0.008])
