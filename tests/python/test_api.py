"""The Python API: loading, model functions, trajectories as arrays, feasibility, progress, GIL."""
import math
import threading
import time

import numpy as np
import pytest

import refdyn
from conftest import MINIMAL_YAML, PAPER_YAML, SOURCE_DIR


def minimal_dict(t1=0.5):
    return {
        "name": "minimal_arm",
        "parameters": {"L1": 0.5, "L2": 0.4},
        "model": {
            "gravity": [0, 0, -9.81],
            "dh": {"convention": "standard", "joints": [
                {"name": "j1", "link": "upper", "type": "revolute", "a": "L1", "mass": 2,
                 "com": [-0.25, 0, 0], "inertia": [0.01, 0.05, 0.05]},
                {"name": "j2", "link": "lower", "type": "revolute", "a": "L2", "mass": 1,
                 "com": [-0.2, 0, 0], "inertia": [0.005, 0.02, 0.02]}]},
            "points": {"E": {"link": "lower", "position": [0, 0, 0]}},
        },
        "constraints": [{"name": "tip_x", "expression": "x(E) - (L1 + 0.1*(1 - cos(2*pi*t))/2)"}],
        "partition": {"independent": ["j2"]},
        "forces": [{"type": "damping", "joint": "j2", "coefficient": 0.5}],
        "initial": {"q": {"j1": 0, "j2": "90*deg"}, "qd": {"j1": 0, "j2": 0}},
        "integrator": {"method": "rk4", "step": 1e-3, "t0": 0, "t1": t1},
    }


@pytest.fixture(scope="module")
def paper_model():
    return refdyn.load(PAPER_YAML).model


# ---------------------------------------------------------------- scenarios

def test_file_text_and_dict_give_the_same_plan():
    from_file = refdyn.plan(MINIMAL_YAML)
    from_text = refdyn.plan(MINIMAL_YAML.read_text())
    from_dict = refdyn.plan(minimal_dict())
    assert from_file.columns == from_text.columns == from_dict.columns
    assert np.array_equal(from_file.data, from_text.data)
    assert np.array_equal(from_file.data, from_dict.data)


def test_paper_file_as_a_yaml_dict_gives_the_same_plan(paper_results):
    yaml = pytest.importorskip("yaml")
    d = yaml.safe_load(PAPER_YAML.read_text())
    assert np.array_equal(refdyn.plan(d).data, paper_results.plan.data)


def test_problem_properties():
    p = refdyn.load(PAPER_YAML)
    assert p.name == "paper_manipulator"
    assert p.joint_names == ["psi1", "psi2", "z3"]
    assert p.t0 == 0 and p.t1 == 5 and p.step == 1e-3
    assert p.q0.shape == (3,) and p.q0[1] == pytest.approx(1.25 * math.pi)
    assert len(p.experiments) == 8 and "a45_nofriction" in p.experiments
    assert p.parameters["b"] == 0.25


# ---------------------------------------------------------------- trajectories

def test_plan_arrays_shapes_dtypes_and_named_columns(paper_results):
    plan = paper_results.plan
    assert isinstance(plan, refdyn.Trajectory)
    n = 5001  # t = 0 .. 5 s every 1 ms
    assert plan.data.dtype == np.float64 and plan.data.shape == (n, len(plan.columns))
    assert plan.data.flags.writeable is False
    assert plan.columns[0] == "t"
    assert plan.joints == ("psi1", "psi2", "z3")
    for name, view in [("q", plan.q), ("qd", plan.qd), ("qdd", plan.qdd)]:
        assert view.shape == (n, 3) and view.dtype == np.float64, name
    assert np.array_equal(plan.q[:, 2], plan["q_z3"])
    assert np.array_equal(plan["psi1"], plan["q_psi1"])
    assert plan.point("E").shape == (n, 3)
    assert "z_a" in plan and "phi_ellipse" in plan.columns
    np.testing.assert_allclose(plan.t, np.linspace(0, 5, n), atol=1e-12)
    with pytest.raises(KeyError, match="no column 'nope'"):
        plan["nope"]
    # the end effector E is on the ellipse and at the prescribed height
    E = plan.point("E")
    a, b = 0.35355339059327373, 0.25
    assert np.max(np.abs((E[500:, 0] / a) ** 2 + (E[500:, 1] / b) ** 2 - 1)) < 1e-6
    assert np.max(np.abs(E[500:, 2] - plan["z_a"][500:])) < 1e-6


def test_feasibility_is_a_dict(paper_results):
    f = paper_results.feasibility
    assert isinstance(f, dict)
    assert isinstance(f["feasible"], bool)
    assert [j["joint"] for j in f["joints"]] == ["psi1", "psi2", "z3"]
    assert refdyn.feasibility(MINIMAL_YAML)["feasible"] in (True, False)


def test_track_returns_runs_per_experiment():
    d = minimal_dict(t1=0.2)
    d["controller"] = {"type": "computed_torque_pd", "delta": {"j1": 20, "j2": 20}}
    d["experiments"] = [{"name": "e{off}", "sweep": {"off": [0.01, 0.02]},
                         "initial": {"q": {"j2": "90*deg + off"}}}]
    r = refdyn.track(d)
    assert list(r.runs) == ["e0.01", "e0.02"]
    run = r.runs["e0.02"]
    assert run.ok and run.data.shape == (201, len(run.columns))
    assert run.tau.shape == (201, 2) and run.q_ref.shape == (201, 2)
    np.testing.assert_array_equal(run.q_ref, r.plan.q)          # the reference is the plan
    assert run.q[0, 1] == pytest.approx(math.pi / 2 + 0.02)
    assert abs(run.q[-1, 1] - run.q_ref[-1, 1]) < 0.02          # the error decays


def test_track_on_threads_gives_the_bits_of_one_thread():
    d = minimal_dict(t1=0.2)
    d["controller"] = {"type": "computed_torque_pd", "delta": {"j1": 20, "j2": 20}}
    d["experiments"] = [{"name": "e{off}", "sweep": {"off": [0.01, 0.02, 0.03, 0.04]},
                         "initial": {"q": {"j2": "90*deg + off"}}}]
    one, two = refdyn.track(d, jobs=1), refdyn.track(d, jobs=2)
    assert list(two.runs) == list(one.runs)
    for name in one.runs:
        np.testing.assert_array_equal(two.runs[name].data, one.runs[name].data)
    st = two.summary["statistics"]
    assert st["runs"] == 4 and st["completed"] == 4
    assert st["peak_abs_tau"]["max"] == max(r["peak_abs_tau"] for r in two.summary["runs"])
    with pytest.raises(refdyn.Error, match="jobs"):
        refdyn.track(d, jobs=-1)
    # A run's summary dict carries its metrics (the RunSummary fields), the numbers of summary.json.
    for rec in two.summary["runs"]:
        s = two.runs[rec["label"]].summary
        assert s["status"] == rec["status"] and s["ok"]
        for key in ("t_end", "saturated_samples", "final_max_abs_error", "peak_abs_tau"):
            assert s[key] == rec[key], key
        assert [j["e0"] for j in s["joints"]] == [j["e0"] for j in rec["joints"]]
        assert [j["peak_tau"] for j in s["joints"]] == [j["peak_abs_tau"] for j in rec["joints"]]


def test_bdf_and_projection_are_chosen_in_the_scenario_dict():
    rk4 = refdyn.plan(minimal_dict())
    d = minimal_dict()
    d["integrator"] = {"method": "bdf", "rtol": 1e-10, "atol": 1e-12, "step": 1e-3, "t0": 0, "t1": 0.5}
    d["stabilization"] = "both"
    bdf = refdyn.plan(d)
    assert bdf.ok, bdf.message
    assert bdf.summary["jacobian_evaluations"] > 0
    assert bdf.summary["newton_iterations"] >= bdf.summary["steps"]
    assert bdf.summary["projections"] >= 0
    assert rk4.summary["jacobian_evaluations"] == 0
    assert np.allclose(bdf.q[-1], rk4.q[-1], rtol=0, atol=1e-6)
    d["integrator"]["max_order"] = 7
    with pytest.raises(refdyn.Error, match="max_order"):
        refdyn.plan(d)


def test_stopped_plan_is_a_status_not_an_exception():
    d = minimal_dict(t1=1.0)
    d["constraints"][0]["expression"] = "x(E) - (L1 + 0.5*t)"   # out of reach near t = 0.8 s
    d["initial"]["consistency"] = "project"
    r = refdyn.run(d)
    assert not r.ok and not r.plan.ok
    assert r.plan.status != "success" and r.plan.message
    assert r.plan.t[-1] < 1.0
    assert r.feasibility["feasible"] is False and r.feasibility.get("incomplete_reason")


def test_runs_on_a_stopped_plan_are_never_a_success():
    # A 3R arm whose tip leaves the workspace (tests/data/stopped/): the plan is cut at its last
    # sample within integrator.residual_tolerance, and each run tracks only that part.
    r = refdyn.track(SOURCE_DIR / "tests" / "data" / "stopped" / "planar_3r_leaves_workspace.yaml")
    assert not r.plan.ok and r.plan.status == "residual above tolerance"
    assert "residual_tolerance" in r.plan.message
    t_end = r.plan.t[-1]
    assert 0.5 < t_end < 2.0 and np.abs(r.plan.q).max() < 10
    assert len(r.runs) == 40
    for name, run in r.runs.items():
        assert not run.ok and run.status == "reference stopped early", name
        assert run.summary["t_end"] == pytest.approx(t_end) and "where the plan stopped" in run.message
    assert all(x["status"] == "reference stopped early" for x in r.summary["runs"])
    assert r.summary["statistics"]["completed"] == 0


# ---------------------------------------------------------------- model functions

def test_model_properties(paper_model):
    m = paper_model
    assert m.nq == 3 and m.joint_names == ["psi1", "psi2", "z3"]
    assert m.point_names == ["E"]
    assert m.total_mass == pytest.approx(31)
    assert m.limits["z3"]["upper"] == 1 and math.isinf(m.limits["psi1"]["lower"])
    np.testing.assert_array_equal(m.gravity, [0, 0, -9.81])


def test_dynamics_are_consistent(paper_model):
    m = paper_model
    rng = np.random.default_rng(1)
    for _ in range(5):
        q, qd, qdd = rng.normal(size=3), rng.normal(size=3), rng.normal(size=3)
        M = m.mass_matrix(q)
        assert M.shape == (3, 3) and M.dtype == np.float64
        np.testing.assert_allclose(M, M.T, atol=1e-12)
        assert np.all(np.linalg.eigvalsh(M) > 0)
        h = m.bias_forces(q, qd)
        tau = m.inverse_dynamics(q, qd, qdd)
        np.testing.assert_allclose(tau, M @ qdd + h, atol=1e-10)
        np.testing.assert_allclose(m.forward_dynamics(q, qd, tau), qdd, atol=1e-9)
        np.testing.assert_allclose(m.gravity_forces(q), m.inverse_dynamics(q, 0 * qd, 0 * qdd), atol=1e-12)
        assert m.kinetic_energy(q, qd) == pytest.approx(0.5 * qd @ M @ qd)
        # g = dV/dq
        eps = 1e-6
        dV = [(m.potential_energy(q + eps * e) - m.potential_energy(q - eps * e)) / (2 * eps) for e in np.eye(3)]
        np.testing.assert_allclose(m.gravity_forces(q), dV, atol=1e-6)


def test_point_kinematics(paper_model):
    m = paper_model
    q = np.array([0.3, 1.25 * math.pi, 0.5])
    r = m.point_position(q, "E")
    assert r.shape == (3,)
    assert r[2] == pytest.approx(0.6 + 0.5 * math.sin(math.pi / 4))   # z0 of the paper
    C = m.point_jacobian(q, "E")
    assert C.shape == (3, 3)
    eps = 1e-7
    Cfd = np.column_stack([(m.point_position(q + eps * e, "E") - m.point_position(q - eps * e, "E")) / (2 * eps)
                           for e in np.eye(3)])
    np.testing.assert_allclose(C, Cfd, atol=1e-7)
    qd = np.array([0.1, -0.2, 0.3])
    v, _ = m.point_velocity(q, qd, "E")
    np.testing.assert_allclose(v, C @ qd, atol=1e-12)
    T = m.link_transform(q, "slider")
    assert T.shape == (4, 4)
    np.testing.assert_allclose(T[:3, 3], r, atol=1e-12)


def test_model_from_section_dh_links_and_urdf():
    d = minimal_dict()
    m = refdyn.model(d["model"], parameters=d["parameters"])
    assert m.nq == 2 and m.joint_names == ["j1", "j2"]
    np.testing.assert_allclose(m.point_position([0, 0], "E"), [0.9, 0, 0], atol=1e-12)
    links = {"links": [
        {"name": "upper", "joint": "j1", "parent": "base", "type": "revolute", "mass": 2,
         "com": [0.25, 0, 0], "inertia": [0.01, 0.05, 0.05]},
        {"name": "lower", "joint": "j2", "parent": "upper", "type": "revolute", "origin": {"xyz": [0.5, 0, 0]},
         "mass": 1, "com": [0.2, 0, 0], "inertia": [0.005, 0.02, 0.02]}],
        "points": {"E": {"link": "lower", "position": [0.4, 0, 0]}}}
    ml = refdyn.model(links)
    q = np.array([0.3, -0.7])
    np.testing.assert_allclose(ml.point_position(q, "E"), m.point_position(q, "E"), atol=1e-12)
    np.testing.assert_allclose(ml.mass_matrix(q), m.mass_matrix(q), atol=1e-12)
    urdf = SOURCE_DIR / "examples" / "urdf" / "arm7.urdf"
    mu = refdyn.load_urdf(urdf)
    assert mu.nq == 7
    assert mu.mass_matrix(np.zeros(7)).shape == (7, 7)
    assert refdyn.parse_urdf(urdf.read_text()).nq == 7
    assert refdyn.model({"urdf": {"file": str(urdf)}}).nq == 7


def test_model_copy_is_independent(paper_model):
    c = paper_model.copy()
    q = np.array([0.1, 0.2, 0.3])
    np.testing.assert_array_equal(c.mass_matrix(q), paper_model.mass_matrix(q))


# ---------------------------------------------------------------- progress, GIL

def test_progress_is_off_by_default(capfd):
    refdyn.plan(MINIMAL_YAML)
    out, err = capfd.readouterr()
    assert out == "" and err == ""


def test_progress_callable_and_bar(capfd):
    calls = []
    refdyn.plan(MINIMAL_YAML, progress=lambda what, t, t0, t1: calls.append((what, t)))
    assert 10 <= len(calls) <= 110 and calls[0][0] == "planning" and calls[-1][1] == pytest.approx(0.5)
    refdyn.plan(MINIMAL_YAML, progress=True)
    _, err = capfd.readouterr()
    assert "planning" in err and "100.0%" in err


def gil_probe(problem):
    """(largest gap between this thread's loop iterations, the run's own wall time) while
    another thread runs refdyn.track(problem)."""
    done = threading.Event()
    result = {}

    def worker():
        result["r"] = refdyn.track(problem)  # plan + 8 closed loops, ~0.2 s
        done.set()

    th = threading.Thread(target=worker)
    stamps = [time.perf_counter()]
    th.start()
    while not done.is_set():
        stamps.append(time.perf_counter())
    th.join()
    return float(np.diff(stamps).max()), result["r"].wall_time


def test_runs_release_the_gil():
    # With the GIL held during the run this thread would stall for the whole run (one gap of
    # about `wall`, every time); released, it keeps running (only the table conversion holds
    # it). Up to three attempts, so that a descheduled moment on a loaded machine is no failure.
    problem = refdyn.load(PAPER_YAML)
    probes = []
    for _ in range(3):
        gap, wall = gil_probe(problem)
        probes.append((gap, wall))
        assert wall > 0.05
        if gap < 0.5 * wall:
            return
    pytest.fail(f"this thread stalled during every run: (largest gap, run wall time) = {probes}")


def test_progress_callback_exception_aborts_the_run():
    seen = []

    def stop(what, t, t0, t1):
        seen.append(t)
        if t > 0.2:
            raise KeyboardInterrupt("stop")

    with pytest.raises(KeyboardInterrupt, match="stop"):
        refdyn.plan(MINIMAL_YAML, progress=stop)
    assert 0.2 < seen[-1] < 0.5
    assert refdyn.plan(MINIMAL_YAML).ok  # nothing left behind


def test_problem_constraints():
    p = refdyn.load(PAPER_YAML)
    c = p.constraints(p.t0, p.q0, p.qd0)
    assert c["rows"] == p.constraint_rows == ["ellipse", "height"]
    assert c["phi"].shape == (2,) and c["A"].shape == (2, 3) and c["gamma"].shape == (2,)
    assert np.max(np.abs(c["phi"])) < 1e-8              # the initial state is consistent
    q, qd, t, eps = p.q0 + [0.2, 0.1, 0.05], np.array([0.3, -0.2, 0.1]), 0.7, 1e-7
    c = p.constraints(t, q, qd)
    A_fd = np.column_stack([(p.constraints(t, q + eps * e, qd)["phi"] - p.constraints(t, q - eps * e, qd)["phi"])
                            / (2 * eps) for e in np.eye(3)])
    np.testing.assert_allclose(c["A"], A_fd, atol=1e-6)
    dphi_dt = (p.constraints(t + eps, q, qd)["phi"] - p.constraints(t - eps, q, qd)["phi"]) / (2 * eps)
    np.testing.assert_allclose(c["phid"], c["A"] @ qd + dphi_dt, atol=1e-6)
    with pytest.raises(refdyn.Error, match="^qd: expected size 3"):
        p.constraints(0.0, q, np.zeros(2))


def test_track_keeps_the_material_constraints_and_motors_only_at_the_actuators():
    # examples/four_bar: the loop closure is kept in the plant, the crank is the only motor.
    path = str(SOURCE_DIR / "examples" / "four_bar" / "four_bar.yaml")
    plant = refdyn.check(path)["plant"]
    assert plant == {"actuators": ["crank"], "assigned": ["crank"], "material_rows": 2}
    r = refdyn.track(path)
    run = r.runs["crank_off"]
    assert run.ok
    assert np.all(run["tau_coupler"] == 0) and np.all(run["tau_rocker"] == 0)
    assert np.abs(run["phi_loop[0]"]).max() < 1e-8 and "reaction_rocker" in run
    s = run.summary
    assert s["max_material_residual"] < 1e-8
    assert s["initial_correction_q"] > 1e-3          # coupler and rocker solved for the crank's error
    t = run.t
    e = run.q[:, 0] - run.q_ref[:, 0]
    np.testing.assert_allclose(e, 0.05 * (1 + 10 * t) * np.exp(-10 * t), atol=1e-6)
