"""The paper study from Python: plan the three-link manipulator, track it from four initial
elevations with and without plant friction, plot. Usage: paper_study.py [out.png]"""
import pathlib
import sys

import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt
import refdyn

scenario = pathlib.Path(__file__).resolve().parents[1] / "paper" / "paper.yaml"
r = refdyn.track(scenario)                      # plan + 8 closed-loop runs, GIL released
plan = r.plan
print(f"plan: {plan.status}, {len(plan)} samples, feasible: {r.feasibility['feasible']}")
fig, ax = plt.subplots(2, 2, figsize=(10, 7))
ax[0, 0].plot(plan.t, plan.q[:, :2], label=["psi1", "psi2"]); ax[0, 0].set_title("joint angles [rad]")
ax[0, 1].plot(plan.t, plan["z3"], label="z3"); ax[0, 1].set_title("slider z3 [m]")
E = plan.point("E")
ax[1, 0].plot(E[:, 0], E[:, 1]); ax[1, 0].set_title("end effector E (x, y)"); ax[1, 0].axis("equal")
for name, run in r.runs.items():
    if name.endswith("_nofriction"):
        ax[1, 1].semilogy(run.t, abs(run["q_psi2"] - run["qref_psi2"]) + 1e-12, label=name)
ax[1, 1].set_title("tracking error |e_psi2| [rad]")
for a in ax.flat:
    a.set_xlabel("t [s]") if a is not ax[1, 0] else None
    a.legend(fontsize=7) if a.get_legend_handles_labels()[0] else None
fig.tight_layout()
out = sys.argv[1] if len(sys.argv) > 1 else "paper_study.png"
fig.savefig(out, dpi=100)
print(f"psi1(1 s) = {plan['psi1'][1000]:.10f} rad, z3(1 s) = {plan['z3'][1000]:.10f} m; figure: {out}")
