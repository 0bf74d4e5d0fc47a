# `cutsim sweep`: the probe over 3 depths x 2 stiffnesses, locally and through GNU parallel, gives
# the same summary (but the wall times); a second sweep skips the jobs that are done.
import csv
import shutil
import subprocess

import pytest

from conftest import SCENES, cutsim_binary

PROBE = str(SCENES / "probe.json")
# short: the probe reaches its depth at 0.06 s (the liver's top is at y = 0.131 m)
AXES = ["--set", "duration=0.06", "--set", "tools.0.keyframes.1.time=0.06",
        "--set", "tools.0.keyframes.1.position.1=0.134,0.130,0.126", "--set", "material.E=30000,60000"]


def sweep(out, *extra):
    p = subprocess.run([cutsim_binary(), "sweep", PROBE, *AXES, "--out", str(out), "--jobs", "2", *extra],
                       capture_output=True, text=True)
    return p.returncode, p.stderr


def rows(out, drop=("wall_time",)):
    with open(out / "summary.csv") as f:
        return [{k: v for k, v in r.items() if k not in drop} for r in csv.DictReader(f)]


@pytest.mark.skipif(shutil.which("parallel") is None, reason="GNU parallel is not installed")
def test_local_and_parallel_give_the_same_summary(tmp_path):
    rc, err = sweep(tmp_path / "local")
    assert rc == 0, err
    assert "6 jobs, 0 done, 6 to run" in err
    local = rows(tmp_path / "local")
    assert len(local) == 6 and all(r["status"] == "ok" for r in local)
    assert len({r["job"] for r in local}) == 6  # a folder a scene
    assert all((tmp_path / "local" / r["job"] / "run" / "report.json").exists() for r in local)
    # deeper and stiffer push harder
    f = {(r["tools.0.keyframes.1.position.1"], r["material.E"]): float(r["tool_force"]) for r in local}
    assert f[("0.126", "30000")] > f[("0.130", "30000")] > f[("0.134", "30000")] > 0
    assert f[("0.126", "60000")] > f[("0.126", "30000")]

    rc, err = sweep(tmp_path / "par", "--engine", "parallel")
    assert rc == 0, err
    assert rows(tmp_path / "par") == local
    assert len((tmp_path / "par" / "jobs.txt").read_text().splitlines()) == 6

    before = (tmp_path / "local" / "summary.csv").read_text()
    rc, err = sweep(tmp_path / "local")
    assert rc == 0 and "6 jobs, 6 done, 0 to run" in err
    assert (tmp_path / "local" / "summary.csv").read_text() == before  # nothing ran again


def test_slurm_script_and_bad_input(tmp_path):
    rc, err = sweep(tmp_path / "s", "--engine", "slurm")
    assert rc == 0, err
    script = (tmp_path / "s" / "sweep.sbatch").read_text()
    assert "#SBATCH --array=1-6" in script and "SLURM_ARRAY_TASK_ID" in script
    assert not (tmp_path / "s" / "summary.csv").exists()
    p = subprocess.run([cutsim_binary(), "sweep", PROBE, "--set", "material.nu=0.3,0.5", "--out", str(tmp_path / "b")],
                       capture_output=True, text=True)
    assert p.returncode == 2 and "material.nu" in p.stderr and p.stderr.startswith("error: ")


def test_a_failed_job_is_a_row_and_exit_1(tmp_path):
    bar = str(SCENES / "bar_sag.json")
    p = subprocess.run([cutsim_binary(), "sweep", bar, "--set", "duration=0.05", "--set", "checks.max_speed=0.0001,100",
                        "--out", str(tmp_path)], capture_output=True, text=True)
    assert p.returncode == 1 and "1 not ok" in p.stderr
    r = rows(tmp_path)
    assert [x["checks.max_speed"] for x in r] == ["0.0001", "100"]
    assert r[0]["status"].startswith("diverged: ") and "," in r[0]["status"]  # quoted in the CSV
    assert r[1]["status"] == "ok" and int(r[1]["steps"]) > int(r[0]["steps"])
