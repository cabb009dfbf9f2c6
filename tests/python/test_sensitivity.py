"""refdyn.sensitivity (docs/sensitivity.md): the same numbers as `refdyn plan --sensitivity`,
as NumPy arrays; a gradient against differences of two plans; bad names as refdyn.Error."""
import json
import subprocess

import numpy as np
import pytest

import refdyn
from conftest import SOURCE_DIR

TRAY = SOURCE_DIR / "examples" / "waiter_tray" / "waiter_tray.yaml"


def test_sensitivity_matches_the_command(cli, tmp_path):
    r = refdyn.sensitivity(TRAY, ["T", "swing"])
    assert r["parameters"] == ["T", "swing"]
    k = len(r["t"])
    assert r["dx"].shape == (k, 4, 2) and r["dqdd"].shape == (k, 2, 2) and r["deffort"].shape == (k, 2, 2)
    assert r["dphi"].shape == (k, 1, 2) and r["dt_end"].shape == (2,)
    out = subprocess.run([str(cli), "plan", str(TRAY), "-o", str(tmp_path / "o"), "-q", "--sensitivity", "T,swing"],
                         capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    js = json.loads((tmp_path / "o" / "sensitivity.json").read_text())
    # equal to rounding: the compiled tapes' operation order follows GiNaC's term order, which
    # depends on what the process built before (docs/sensitivity.md)
    for m in js["metrics"]:
        g = r["metrics"][m["name"]]["gradient"]
        assert g[0] == pytest.approx(m["gradient"]["T"], rel=1e-12, abs=1e-300), m["name"]
        assert g[1] == pytest.approx(m["gradient"]["swing"], rel=1e-12, abs=1e-300), m["name"]
    # the final q1 against central differences of two plans
    h = 1e-5

    def final_q1(T):
        text = TRAY.read_text().replace("  T: 2.0 ", f"  T: {T!r} ")
        return refdyn.plan(refdyn.loads(text)).q[-1, 0]

    fd = (final_q1(2.0 + h) - final_q1(2.0 - h)) / (2 * h)
    assert r["metrics"]["final_q(q1)"]["gradient"][0] == pytest.approx(fd, rel=1e-6)


def test_bad_names_raise_with_a_hint():
    with pytest.raises(refdyn.Error, match="did you mean 'T'"):
        refdyn.sensitivity(TRAY, "Tx")
    with pytest.raises(refdyn.Error, match="at least one"):
        refdyn.sensitivity(TRAY, [])
