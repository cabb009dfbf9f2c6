"""Errors: refdyn.Error (a ValueError) with exactly the CLI's one-line message."""
import subprocess

import numpy as np
import pytest

import refdyn
from conftest import BAD_DIR, MINIMAL_YAML, PAPER_YAML

BAD_FILES = sorted(p.name for p in BAD_DIR.glob("*.yaml"))


def cli_message(cli, path, tmp_path):
    r = subprocess.run([str(cli), "plan", str(path), "-q", "-o", str(tmp_path / "out")],
                       capture_output=True, text=True)
    assert r.returncode == 2, (r.returncode, r.stderr)
    lines = r.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("refdyn: error: "), r.stderr
    return lines[0][len("refdyn: error: "):]


@pytest.mark.parametrize("name", BAD_FILES)
def test_bad_scenario_raises_the_cli_message(cli, tmp_path, name):
    path = BAD_DIR / name
    with pytest.raises(refdyn.Error) as e:
        refdyn.run(path)
    assert str(e.value) == cli_message(cli, path, tmp_path)
    assert "\n" not in str(e.value)


def test_error_classes():
    assert issubclass(refdyn.Error, ValueError)
    assert issubclass(refdyn.NumericalFailure, refdyn.Error)


def test_missing_file_and_bad_text():
    with pytest.raises(refdyn.Error, match="nonexistent.yaml"):
        refdyn.load("nonexistent.yaml")
    with pytest.raises(refdyn.Error, match=r"^<string>:\d+: "):
        refdyn.loads("name: x\nmodel: [1, 2\n")
    with pytest.raises(TypeError):
        refdyn.load(42)


def test_dict_errors_name_the_key():
    d = {"model": {"dh": {"joints": [{"name": "j1", "type": "revolute", "a": 1, "mass": -1}]}},
         "initial": {"q": [0]}}
    with pytest.raises(refdyn.Error, match=r"^<dict>:\d+: model\.dh\.joints\[0\]\.mass: "):
        refdyn.from_dict(d)


def test_model_function_argument_errors():
    m = refdyn.load(PAPER_YAML).model
    with pytest.raises(refdyn.Error, match=r"^q: expected size 3, got size 2"):
        m.mass_matrix(np.zeros(2))
    with pytest.raises(refdyn.Error, match="finite"):
        m.mass_matrix(np.array([0, np.nan, 0]))
    with pytest.raises(refdyn.Error, match="did you mean 'E'"):
        m.point_position(np.zeros(3), "F")
    with pytest.raises(refdyn.Error, match=r"^q: expected a 1-D array, got 2 dimensions"):
        m.mass_matrix(np.zeros((3, 1)))
    with pytest.raises(refdyn.Error, match=r"^qd: expected size 3, got size 4"):
        m.bias_forces(np.zeros(3), np.zeros(4))
    with pytest.raises(TypeError):
        m.mass_matrix("abc")
    np.testing.assert_array_equal(m.mass_matrix([0.1, 0.2, 0.3]), m.mass_matrix(np.array([0.1, 0.2, 0.3])))


def test_track_without_experiments():
    with pytest.raises(refdyn.Error, match="experiments: missing"):
        refdyn.track(MINIMAL_YAML)
