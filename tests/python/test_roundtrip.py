"""The paper study planned from Python equals the C++ CLI's result, bit for bit."""
import json
import subprocess

import numpy as np
import pytest

from conftest import PAPER_YAML


@pytest.fixture(scope="module")
def cli_plan(cli, tmp_path_factory):
    out = tmp_path_factory.mktemp("cli_plan")
    subprocess.run([str(cli), "plan", str(PAPER_YAML), "-q", "-o", str(out)], check=True)
    with open(out / "plan.csv") as f:
        header = f.readline().strip().split(",")
    data = np.loadtxt(out / "plan.csv", delimiter=",", skiprows=1, ndmin=2)
    feas = json.loads((out / "feasibility.json").read_text())
    summary = json.loads((out / "summary.json").read_text())
    return header, data, feas, summary


def test_plan_equals_cli_plan_csv_bit_for_bit(paper_results, cli_plan):
    header, data, _, _ = cli_plan
    plan = paper_results.plan
    assert list(plan.columns) == header
    assert plan.data.shape == data.shape
    # 17 significant digits in the CSV: parsing gives back the very doubles.
    assert np.array_equal(plan.data, data), np.max(np.abs(plan.data - data))


def test_feasibility_dict_equals_cli_feasibility_json(paper_results, cli_plan):
    _, _, feas, _ = cli_plan
    assert paper_results.feasibility == feas


def test_summary_plan_section_equals_cli(paper_results, cli_plan):
    _, _, _, summary = cli_plan
    ours = dict(paper_results.summary)
    for s in (ours, summary):  # wall times differ from run to run
        s["plan"].pop("wall_time_s")
        s.pop("wall_time_s")
    assert ours == summary


def test_paper_study_pinned_numbers(paper_results):
    plan = paper_results.plan
    i = int(np.argmin(np.abs(plan.t - 1.0)))
    assert plan.t[i] == pytest.approx(1.0, abs=1e-12)
    assert plan["psi1"][i] == pytest.approx(0.3055615672, abs=1e-9)
    assert plan["q_z3"][i] == pytest.approx(0.5150243835, abs=1e-9)
    assert plan.ok and plan.status == "success"


def test_written_results_equal_cli_files(paper_results, cli_plan, tmp_path):
    paper_results.write(tmp_path)
    data = np.loadtxt(tmp_path / "plan.csv", delimiter=",", skiprows=1, ndmin=2)
    assert np.array_equal(data, cli_plan[1])
