# Shared helpers of the Python tests: the checkout, the cutsim command, a run of it.
import json
import os
import subprocess
from pathlib import Path

import pytest

SOURCE = Path(__file__).resolve().parents[2]
SCENES = SOURCE / "assets" / "scenes"


def cutsim_binary():
    b = os.environ.get("CUTSIM_BINARY")
    if not b or not Path(b).exists():
        pytest.skip("CUTSIM_BINARY is not set (ctest sets it)")
    return b


def run_cli(args, out):
    """`cutsim ARGS --out OUT`: its exit code, stderr and report (None when there is none)."""
    p = subprocess.run([cutsim_binary(), *args, "--out", str(out)], capture_output=True, text=True)
    report = out / "report.json"
    return p.returncode, p.stderr, json.loads(report.read_text()) if report.exists() else None


def vtu_points(path):
    """The node positions of a final.vtu (ascii, shortest round-trip numbers): exact floats."""
    text = Path(path).read_text()
    start = text.index(">", text.index('NumberOfComponents="3"', text.index("<Points>"))) + 1
    values = [float(v) for v in text[start : text.index("</DataArray>", start)].split()]
    return [values[i : i + 3] for i in range(0, len(values), 3)]
