"""refdyn.check, refdyn.generate, refdyn.run_variants and Problem.constraint_rows (issue 22, item 4):
each against what the command line gives for the same scenario (refdyn check / generate / plan)."""
import json
import subprocess

import numpy as np
import pytest
import yaml

import refdyn
from conftest import BAD_DIR, MINIMAL_YAML, PAPER_YAML, SOURCE_DIR

EXAMPLES = SOURCE_DIR / "examples"
FAMILY = EXAMPLES / "planar_2r_circle" / "family.yaml"
MIXED = EXAMPLES / "mixed_orders" / "mixed_orders.yaml"


def cli_out(cli, *args, cwd=None):
    return subprocess.run([str(cli), *map(str, args)], capture_output=True, text=True, cwd=cwd)


def minimal_jerk():
    """tests/data/good/minimal.yaml's arm with a jerk row (order 3) on the tip, as a dict."""
    d = yaml.safe_load(MINIMAL_YAML.read_text())
    d["constraints"] = [{"name": "tip_jerk", "order": "jerk", "expression": "jx(E) - 0.1*cos(t)"}]
    return d


# ---------------------------------------------------------------- check
@pytest.mark.parametrize("path", [PAPER_YAML, FAMILY, EXAMPLES / "four_bar" / "four_bar.yaml",
                                  EXAMPLES / "unicycle" / "unicycle.yaml", EXAMPLES / "waiter_tray" / "waiter_tray.yaml",
                                  EXAMPLES / "stiff_friction" / "stick_slip.yaml", MINIMAL_YAML],
                         ids=lambda p: p.name)
def test_check_text_is_the_command_output_byte_for_byte(cli, path):
    r = refdyn.check(path)
    out = cli_out(cli, "check", path)
    assert out.returncode == 0, out.stderr
    assert r["text"] == out.stdout
    assert r["valid"] is True and r["file"] == str(path)
    rows = r["rows"]
    assert rows["total"] == rows["material"] + rows["programmed"]
    assert rows["total"] == rows["holonomic"] + rows["first_order"] + rows["acceleration"] + rows["jerk"]
    assert rows["total"] == sum(c["rows"] for c in r["constraints"])
    assert list(r["residuals"]) == list(refdyn.load(path).constraint_rows)
    for c in r["constraints"]:
        assert f"  {c['name']}: {c['origin']}, {c['kind']}, " in r["text"]


def test_check_dict_fields_of_the_paper_example():
    r = refdyn.check(PAPER_YAML)
    assert r["scenario"] == "paper_manipulator"
    assert r["joints"] == ["psi1", "psi2", "z3"]
    assert [c["name"] for c in r["constraints"]] == ["ellipse", "height"]
    assert [c["rheonomic"] for c in r["constraints"]] == [False, True]
    assert r["partition"]["independent"] == ["psi1"] and r["partition"]["dependent"] == ["psi2", "z3"]
    assert r["partition"]["condition"] > 1
    assert r["partition"]["used_by_solver"] is True  # the paper's 3 coordinates: the projection solver
    assert f"cond(K_dc) = {r['partition']['condition']:.6g}" in r["text"]
    assert r["integrator"]["method"] == "rk4" and r["integrator"]["step"] == 1e-3
    assert r["experiments"] == 8 and r["variants"] == []
    assert r["initial_acceleration"] is None
    assert all(set(v) == {"|Phi|", "|dPhi/dt|"} for v in r["residuals"].values())
    assert r["model"] in r["text"]


def test_check_variants_projection_and_sources(cli):
    r = refdyn.check(FAMILY)
    assert len(r["variants"]) == 6 and r["variants"][0] == "R0.1_T1"
    assert "variants: 6 (R0.1_T1, R0.1_T2, R0.15_T1, …; each is checked when it is planned)" in r["text"]
    assert (r["projection"] is not None) == ("initial state projected" in r["text"])
    # YAML text and a dict give the same report (named <string> / <dict>)
    text = FAMILY.read_text()
    s = refdyn.check(text)
    assert s["file"] == "<string>"
    assert s["text"] == r["text"].replace(f"({FAMILY})", "(<string>)")
    d = refdyn.check(yaml.safe_load(text))
    assert d["text"] == r["text"].replace(f"({FAMILY})", "(<dict>)")
    named = refdyn.check(text, source_name=str(FAMILY))  # a text named as its file: the same report
    assert named["text"] == r["text"]


def test_check_of_a_jerk_problem_reports_the_initial_acceleration():
    r = refdyn.check(minimal_jerk())
    assert r["rows"]["jerk"] == 1
    assert r["constraints"][0]["order"] == 3 and r["constraints"][0]["kind"] == "jerk-level"
    assert r["initial_acceleration"]["source"] == "free"
    assert set(r["initial_acceleration"]["values"]) == {"j1", "j2"}


def test_check_of_a_mixed_order_problem_reports_rows_of_every_order_and_the_consistent_acceleration():
    r = refdyn.check(MIXED)
    assert [(c["name"], c["order"]) for c in r["constraints"]] == [("height", 0), ("wrist", 3)]
    assert r["rows"]["holonomic"] == 1 and r["rows"]["jerk"] == 1
    assert r["initial_acceleration"]["source"] == "consistent_with"
    assert r["initial_acceleration"]["consistent_with"] == ["wrist"]
    assert r["partition"] is None and "no partition" in r["planner"]
    rows = refdyn.load(MIXED).constraint_rows
    assert [(row, row.order) for row in rows] == [("height", 0), ("wrist", 3)]


@pytest.mark.parametrize("name", ["variants_unknown_parameter.yaml", "order_jerk.yaml"])
def test_check_of_a_bad_scenario_raises_the_command_message(cli, name):
    path = BAD_DIR / name
    out = cli_out(cli, "check", path)
    assert out.returncode == 2
    with pytest.raises(refdyn.Error) as e:
        refdyn.check(path)
    assert out.stderr.strip() == "refdyn: error: " + str(e.value)


def test_check_rejects_other_types():
    with pytest.raises(TypeError):
        refdyn.check(42)


# ---------------------------------------------------------------- constraint rows
def test_constraint_rows_are_names_with_order_origin_and_kind():
    p = refdyn.load(PAPER_YAML)
    rows = p.constraint_rows
    assert rows == ["ellipse", "height"]  # still the names
    assert all(isinstance(r, str) and isinstance(r, refdyn.ConstraintRow) for r in rows)
    assert [(r.order, r.origin, r.kind, r.rheonomic) for r in rows] == [
        (0, "programmed", "holonomic", False), (0, "programmed", "holonomic", True)]
    assert rows[0].order_label == "holonomic (position)"
    assert rows[0].as_dict()["name"] == "ellipse" and "ellipse" in repr(rows[0])
    assert p.constraints(0.0, p.q0, p.qd0)["rows"] == rows


def test_constraint_rows_of_every_order_and_origin():
    four_bar = refdyn.load(EXAMPLES / "four_bar" / "four_bar.yaml").constraint_rows
    assert {r.origin for r in four_bar} >= {"material"}
    multi = [r for r in four_bar if r.name != r.constraint]
    assert multi and all(r.name == f"{r.constraint}[{r.index}]" for r in multi)
    unicycle = refdyn.load(EXAMPLES / "unicycle" / "unicycle.yaml").constraint_rows
    assert any(r.order == 1 and r.kind == "first-order" for r in unicycle)
    waiter = refdyn.load(EXAMPLES / "waiter_tray" / "waiter_tray.yaml").constraint_rows
    assert [(r.order, r.kind, r.order_label) for r in waiter] == [(2, "acceleration-level", "acceleration (order 2)")]
    jerk = refdyn.load(minimal_jerk()).constraint_rows
    assert [(r.name, r.order, r.kind, r.origin, r.rheonomic) for r in jerk] == [
        ("tip_jerk", 3, "jerk-level", "programmed", True)]
    assert jerk[0].order_label == "jerk (order 3)"


# ---------------------------------------------------------------- generate
def json_shape(x):
    """The keys (recursively) and list lengths of a JSON value, without the texts and numbers."""
    if isinstance(x, dict):
        return {k: json_shape(v) for k, v in x.items()}
    if isinstance(x, list):
        return [json_shape(v) for v in x]
    return type(x).__name__


def test_generate_gives_the_files_of_the_command(cli, tmp_path):
    # The generator's text is canonical (docs/generate.md, "The same text in every run"): the
    # Python call returns the command's files byte for byte.
    out = cli_out(cli, "generate", PAPER_YAML, "-o", tmp_path, "--format", "c,latex,json", "--prefix", "arm_", "-q")
    assert out.returncode == 0, out.stderr
    g = refdyn.generate(PAPER_YAML, prefix="arm_")
    assert set(g) == {"c_header", "c_source", "latex", "json"}
    assert g["c_header"] == (tmp_path / "reference_dynamics.h").read_text()
    assert g["c_source"] == (tmp_path / "reference_dynamics.c").read_text()
    assert g["latex"] == (tmp_path / "equations.tex").read_text()
    assert g["json"] == (tmp_path / "reference_dynamics.json").read_text()
    assert json_shape(json.loads(g["json"])) == json_shape(json.loads((tmp_path / "reference_dynamics.json").read_text()))


def test_generate_formats_sources_and_errors():
    p = refdyn.load(PAPER_YAML)
    assert set(refdyn.generate(p, formats="latex")) == {"latex"}
    assert set(refdyn.generate(p, formats=["c", "json"])) == {"c_header", "c_source", "json"}
    assert refdyn.generate(PAPER_YAML.read_text(), formats="c")["c_header"] == refdyn.generate(p, formats="c")["c_header"]
    with pytest.raises(refdyn.Error, match="formats: expected a comma-separated list of c, latex, json, got 'pdf'"):
        refdyn.generate(p, formats="c,pdf")
    with pytest.raises(refdyn.Error, match="at least one"):
        refdyn.generate(p, formats=[])
    with pytest.raises(refdyn.Error, match="prefix '1bad' is not a C identifier"):
        refdyn.generate(p, prefix="1bad")
    jerk = refdyn.generate(minimal_jerk())  # jerk problems generate too: state [q, qd, qdd, z]
    assert "qddd" in jerk["json"] or "jerk" in jerk["c_header"]
    assert "_jerk(" in jerk["c_header"]


# ---------------------------------------------------------------- variants
def test_run_variants_matches_refdyn_plan(cli, tmp_path):
    out = cli_out(cli, "plan", FAMILY, "-o", tmp_path / "cli", "-q")
    assert out.returncode == 0, out.stderr
    calls = []
    r = refdyn.run_variants(FAMILY, jobs=2, directory=tmp_path / "py", progress=lambda *a: calls.append(a))
    assert r.ok and len(r) == 6 and r.joints == ("q1", "q2")
    assert r.csv == (tmp_path / "cli" / "variants.csv").read_text()
    assert (tmp_path / "py" / "variants.csv").read_text() == r.csv
    cli_summary = json.loads((tmp_path / "cli" / "summary.json").read_text())
    py_summary = json.loads((tmp_path / "py" / "summary.json").read_text())

    def without_wall_times(x):
        if isinstance(x, dict):
            return {k: without_wall_times(v) for k, v in x.items() if "wall_time" not in k}
        if isinstance(x, list):
            return [without_wall_times(v) for v in x]
        return x
    assert without_wall_times(py_summary) == without_wall_times(cli_summary)
    assert without_wall_times(r.summary) == without_wall_times(py_summary)  # what was written
    for v in r.variants:  # a folder per variant, as the command writes
        assert (tmp_path / "py" / v["name"] / "plan.csv").read_bytes() == (tmp_path / "cli" / v["name"] / "plan.csv").read_bytes()
    assert sorted(c[0] for c in calls) == list(range(1, 7)) and all(c[1] == 6 for c in calls)
    assert {c[2] for c in calls} == {v["name"] for v in r.variants}
    v = r["R0.15_T2"]
    assert v["values"] == {"R": 0.15, "Tp": 2.0} and v["status"] == "success" and v["feasible"] in (True, False)
    assert len(v["peak_speed"]) == 2
    assert r.column("t_end").shape == (6,)


def test_run_variants_threads_give_the_same_results():
    a = refdyn.run_variants(FAMILY, jobs=1)
    b = refdyn.run_variants(FAMILY, jobs=3)
    assert a.csv == b.csv
    strip = lambda r: [{k: x for k, x in v.items() if k != "wall_time"} for v in r.variants]
    assert strip(a) == strip(b)


def test_run_variants_invalid_variant_is_a_result_not_an_exception():
    d = yaml.safe_load(FAMILY.read_text())
    d["variants"] = {"name": "R{R}", "grid": {"R": [0.15, 5.0]}}  # R = 5 m: out of the arm's reach
    r = refdyn.run_variants(d)
    assert not r.ok
    bad = [v for v in r.variants if not v["ok"]]
    assert len(bad) == 1 and bad[0]["values"]["R"] == 5.0
    assert bad[0]["status"] == "invalid" and bad[0]["error"]


def test_run_variants_errors(tmp_path):
    with pytest.raises(refdyn.Error, match="variants: missing"):
        refdyn.run_variants(PAPER_YAML)
    with pytest.raises(refdyn.Error, match="jobs"):
        refdyn.run_variants(FAMILY, jobs=-1)
    with pytest.raises(refdyn.Error) as e:
        refdyn.run_variants(BAD_DIR / "variants_unknown_parameter.yaml")
    assert "variants" in str(e.value)
    with pytest.raises(TypeError):
        refdyn.run_variants(FAMILY, progress=3)

    class Stop(Exception):
        pass

    def stop(done, total, name):
        raise Stop(name)
    with pytest.raises(Stop):
        refdyn.run_variants(FAMILY, progress=stop)
