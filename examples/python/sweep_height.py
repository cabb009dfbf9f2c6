"""A parameter sweep in plain Python: the paper scenario with a growing height excursion dz of
the end effector; for each value, the peak actuator efforts and whether the plan is feasible.
Usage: sweep_height.py [dz ...]"""
import pathlib
import sys

import numpy as np
import yaml  # python3-yaml: the scenario as a dict
import refdyn

path = pathlib.Path(__file__).resolve().parents[1] / "paper" / "paper.yaml"
base = yaml.safe_load(path.read_text())
base.pop("experiments")  # planning only
values = [float(v) for v in sys.argv[1:]] or [0.1, 0.3, 0.5, 0.6, 0.9]
print(f"{'dz [m]':>7} {'status':>8} {'feasible':>8}  peak |required effort| per joint; violations")
for dz in values:
    scenario = dict(base, parameters=dict(base["parameters"], dz=dz))
    r = refdyn.run(scenario)
    plan = r.plan
    peak = np.abs(plan.group("required_")).max(axis=0)
    efforts = ", ".join(f"{j} {p:7.2f}" for j, p in zip(plan.joints, peak))
    bad = "; ".join(f"{v['joint']} {v['quantity']} {v['worst']:.3g} (limit {v['limit']:g})"
                    for v in r.feasibility["violations"])
    print(f"{dz:7.2f} {plan.status:>8} {str(r.feasibility['feasible']):>8}  {efforts}  {bad}")
