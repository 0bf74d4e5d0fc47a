# The Python module against the CLI: the same run bitwise, cuts, a tool force loop, errors.
import json

import numpy as np
import pytest

import cutsim
from conftest import SCENES, run_cli, vtu_points

BAR = str(SCENES / "bar_sag.json")
PROBE = str(SCENES / "probe.json")
SHORT = ["duration=0.05"]


def test_final_positions_bitwise_equal_to_cli(tmp_path):
    rc, err, report = run_cli(["run", BAR, "--no-render", "--quiet", "--threads", "1", "--set", SHORT[0]], tmp_path)
    assert rc == 0, err
    sim = cutsim.Simulation(BAR, set=SHORT, threads=1)
    sim.run()
    assert sim.status == "ok"
    assert sim.steps == report["steps"] > 100
    assert sim.state_hash() == report["state_hash"]
    cli = np.array(vtu_points(tmp_path / "final.vtu"))
    assert cli.shape == sim.positions.shape
    assert np.array_equal(cli, sim.positions)  # bitwise: the VTU holds round-trip numbers
    assert not np.array_equal(sim.positions, sim.rest_positions)  # it did sag


def test_dict_scene_and_steps(tmp_path):
    scene = json.loads((SCENES / "bar_sag.json").read_text())
    scene["duration"] = 0.05
    a = cutsim.Simulation(scene, threads=1)
    b = cutsim.Simulation(BAR, set=SHORT, threads=1)
    assert a.step(10) == 10 and a.steps == 10
    while not b.finished:
        b.step()
    a.run()
    assert a.state_hash() == b.state_hash()
    assert a.step(5) == 0  # the scene's end: no more steps


def test_arrays_are_views_that_follow_the_state():
    sim = cutsim.Simulation(BAR, set=SHORT, threads=1)
    x = sim.positions
    assert x.shape == (sim.nodes, 3) and x.dtype == np.float64
    assert not x.flags.writeable and not x.flags.owndata
    before = x.copy()
    sim.step(20)
    assert not np.array_equal(before, x)  # the same memory, moved by the steps
    assert np.array_equal(x, sim.positions)
    v = sim.velocities
    assert v.shape == x.shape and np.abs(v).max() > 0
    es = sim.element_steps
    assert es.shape == (sim.elements,) and es.min() > 0
    lim, init = sim.limits, sim.initial_limits
    assert 0 < init["certified"] <= init["exact"]
    assert sim.dt == pytest.approx(0.9 * init["exact"])
    assert lim["certified"] == init["certified"]
    crit = sim.critical_elements
    assert crit.dtype == np.int32 and (es[crit] < 1.1 * sim.dt).all()
    del sim
    assert x.sum() != 0  # the view keeps the simulation alive


def test_cut_through_the_bar():
    sim = cutsim.Simulation(BAR, set=["duration=0.3"], threads=1)
    sim.step(50)
    n0, e0 = sim.nodes, sim.elements
    r = sim.cut_plane([0.51, 0.05, 0.0], [1, 0, 0])
    assert r["crossed"] > 0 and r["split"] > 0 and r["new_nodes"] > 0
    assert sim.nodes == n0 + r["new_nodes"] and sim.elements > e0 and sim.cuts == 1
    sim.run()
    x = sim.positions
    rep = sim.report()
    assert rep["pieces"] == 2 and len(rep["cuts"]) == 1
    # the free half falls away while the clamped half stays: the tip drops far more than at x < 0.5
    tip = x[:, 0] > 0.9
    assert x[tip, 2].mean() < -0.1


def test_polygon_cut_leaves_one_piece():
    sim = cutsim.Simulation(BAR, set=["duration=0.1"], threads=1)
    # a slit through the top half only
    r = sim.cut_polygon([0.51, 0.05, 0.05], [1, 0, 0], [[0.51, -1, 0.06], [0.51, 1, 0.06], [0.51, 1, 0.2], [0.51, -1, 0.2]])
    assert r["split"] > 0
    sim.run()
    assert sim.report()["pieces"] == 1


def test_tool_force_in_a_loop():
    sim = cutsim.Simulation(PROBE, set=["duration=0.2"], threads=1)
    assert sim.tool_names == ["probe"]
    forces = []
    for k in range(40):
        y = 0.145 - 0.0006 * k  # down into the liver (its top: y = 0.131 m)
        sim.set_tool(0, [0.0, y, 0.008])
        sim.step(int(0.004 / sim.dt) + 1)
        forces.append(np.linalg.norm(sim.tool_force(0)))
        assert np.allclose(sim.tool_position(0), [0.0, y, 0.008])
    assert forces[0] == 0  # above the surface
    assert max(forces) > 0.05
    assert forces[-1] > forces[len(forces) // 2] > 0  # deeper pushes harder
    with pytest.raises(IndexError):
        sim.tool_force(1)


def test_from_arrays_matches_the_box_scene():
    box = cutsim.Simulation(BAR, set=SHORT, threads=1)
    nodes = np.array(box.rest_positions)
    tets = box.tets
    scene = json.loads((SCENES / "bar_sag.json").read_text())
    mat = scene.pop("material")
    del scene["object"]
    scene["duration"] = 0.05
    arr = cutsim.Simulation.from_arrays(nodes, tets, mat, scene, threads=1)
    assert arr.nodes == box.nodes and arr.elements == box.elements
    arr.run()
    box.run()
    assert arr.state_hash() == box.state_hash()


def test_errors_are_the_cli_messages(tmp_path):
    bad = ["material.nu=0.5"]
    rc, err, _ = run_cli(["run", BAR, "--no-render", "--set", bad[0]], tmp_path)
    assert rc == 2
    with pytest.raises(cutsim.InputError) as e:
        cutsim.Simulation(BAR, set=bad)
    assert err.strip() == "error: " + str(e.value)
    assert "material.nu" in str(e.value)
    with pytest.raises(cutsim.InputError, match="file not found"):
        cutsim.Simulation(str(tmp_path / "none.json"))
    with pytest.raises(cutsim.InputError, match="tets"):
        cutsim.Simulation.from_arrays(np.zeros((4, 3)), np.array([[0, 1, 2, 9]]), {"E": 1e4, "nu": 0.3, "rho": 1000})


def test_a_diverged_step_raises(tmp_path):
    # 41x the exact limit, held by per-element damping it cannot hold: the checks stop the run
    blowup = ['integrator.dt={"mode":"fixed","value":0.016666666666666666,"on_limit":"damp"}']
    rc, _, report = run_cli(["run", BAR, "--no-render", "--quiet", "--set", blowup[0]], tmp_path)
    assert rc == 3
    sim = cutsim.Simulation(BAR, set=blowup, threads=1)
    with pytest.raises(cutsim.SimulationError) as e:
        sim.step(1000)
    assert str(e.value) == report["status"] and str(e.value).startswith("diverged:")
    assert sim.status == "diverged" and sim.steps == report["steps"] < 90
    with pytest.raises(cutsim.SimulationError):
        sim.step()  # and it stays failed


def test_report_written(tmp_path):
    sim = cutsim.Simulation(BAR, set=SHORT, threads=1)
    sim.run()
    rep = sim.report(str(tmp_path / "report.json"))
    on_disk = json.loads((tmp_path / "report.json").read_text())
    assert on_disk["state_hash"] == rep["state_hash"] == sim.state_hash()
    assert rep["status"] == "ok"
