"""refdyn.optimize (docs/optimize.md): the same optimum and optimization.csv as `refdyn optimize`,
the history as NumPy arrays, bad sections as refdyn.Error."""
import numpy as np
import pytest

import refdyn
from conftest import SOURCE_DIR, BAD_DIR

DURATION = SOURCE_DIR / "examples" / "paper" / "duration.yaml"


def test_optimize_matches_the_command(cli, tmp_path):
    import subprocess
    r = refdyn.optimize(DURATION)
    assert r["feasible"] and r["method"] == "cobyla"
    assert set(r["best"]) == {"Td"} and 4.18 < r["best"]["Td"] < 4.20
    assert r["objective"] == r["best"]["Td"]
    h = r["history"]
    n = r["evaluations"]
    assert isinstance(h["x"], np.ndarray) and h["x"].shape == (n, 1)
    assert h["constraints"].shape == (n, len(r["constraint_names"]))
    assert h["objective"].shape == (n,) and h["feasible"].dtype == bool
    assert h["feasible"].any() and h["ok"].all()
    # every feasible row has every g <= 0
    assert (h["constraints"][h["feasible"]] <= 0).all()
    out = subprocess.run([str(cli), "optimize", str(DURATION), "-o", str(tmp_path / "o"), "-q"],
                         capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert (tmp_path / "o" / "optimization.csv").read_text() == r["csv"]


def test_optimize_overrides_and_errors():
    r = refdyn.optimize(DURATION, budget=2)
    assert r["evaluations"] == 2 and r["status"] == "budget"
    with pytest.raises(refdyn.Error, match="did you mean 'L2'"):
        refdyn.optimize(BAD_DIR / "optimize_unknown_variable.yaml")
    with pytest.raises(refdyn.Error, match="--method"):
        refdyn.optimize(DURATION, method="nelder")
    with pytest.raises(ValueError):
        refdyn.optimize(DURATION, budget=0)


def test_phase_plane_retimes_the_circle():
    """method: phase_plane (docs/optimize.md, "Time-optimal retiming"): the 2R circle's 128-part
    knot-speed law within the limits, a few plans, the feasible optimum within 2 % of T* = 0.906705 s."""
    r = refdyn.optimize(SOURCE_DIR / "examples" / "planar_2r_circle" / "retime_speeds.yaml")
    assert r["method"] == "phase_plane" and r["feasible"] and r["status"] == "success"
    assert len(r["best"]) == 127 and r["evaluations"] <= 9
    assert 0.906705 < r["objective"] < 1.02 * 0.906705
    assert "TOPP-RA" in r["message"]
    with pytest.raises(refdyn.Error, match="knot_speeds form"):
        refdyn.optimize(DURATION, method="phase_plane")
