#!/usr/bin/env bash
# Self-test of scripts/plot_study.py on synthetic study output (nothing is committed):
#   1. writes plan.csv, track_*.csv and summary.json with the study's exact columns and
#      plausible shapes into a temporary folder (kept with KEEP=1, or give it as $1),
#   2. runs the plotter and checks every figure exists as PNG and PDF,
#   3. checks that a missing column, a missing file, binary / non-UTF-8 / corrupted / empty
#      CSVs and a broken summary.json fail with one line "refdyn: error: FILE: ...", exit 2,
#      and leave no temporary or partial figure behind; figures get mode 0666 minus the umask.
# Uses Debian's /usr/bin/python3 (matplotlib); override with PYTHON=...
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-/usr/bin/python3}
DIR=${1:-$(mktemp -d /tmp/plot_study_selftest.XXXXXX)}
mkdir -p "$DIR"
if [[ -z "${1:-}" && -z "${KEEP:-}" ]]; then trap 'rm -rf "$DIR"' EXIT; fi

"$PY" - "$DIR" <<'EOF'
"""Synthetic study output: the paper's kinematics, a cycloidal drive, errors e0(1+dt)e^-dt."""
import json, math, os, sys
import numpy as np

out = sys.argv[1]
T, h1, a, b, dz = 5.0, 0.6, 0.5 * math.cos(math.pi / 4), 0.25, 0.1
t = np.linspace(0.0, T, 5001)
rng = np.random.default_rng(1)

def cyc(t):  # 0 -> 2 pi over T
    return 2 * np.pi * (t / T - np.sin(2 * np.pi * t / T) / (2 * np.pi))

def d(x):
    return np.gradient(x, t)

def fk(q1, q2, q3):  # standard DH of paper_manipulator.hpp, E at the origin of frame 3
    return (-q3 * np.sin(q2) * np.cos(q1), -q3 * np.sin(q2) * np.sin(q1), h1 - q3 * np.cos(q2))

def write(name, cols):
    keys = list(cols)
    np.savetxt(os.path.join(out, name), np.column_stack([cols[k] for k in keys]),
               delimiter=",", header=",".join(keys), comments="", fmt="%.17g")

psi_dr = cyc(t)
tau_drive = 0.8 * d(d(psi_dr)) + 0.15 * np.tanh(d(psi_dr) / 0.01) + 0.3 * np.sin(2 * psi_dr)
psi1 = psi_dr - tau_drive / 1e4
r = a * b / np.sqrt((b * np.cos(psi1)) ** 2 + (a * np.sin(psi1)) ** 2)
z_a = h1 + 0.5 * math.sin(math.pi / 4) + dz * (1 - np.cos(2 * np.pi * t / T)) / 2
eps = np.arctan2(z_a - h1, r)
psi2 = 1.5 * np.pi - eps
z3 = np.hypot(r, z_a - h1)
q = {"psi1": psi1, "psi2": psi2, "z3": z3}
Ex, Ey, Ez = fk(psi1, psi2, z3)
plan = {"t": t}
for p, f in (("q", lambda x: x), ("qd", d), ("qdd", lambda x: d(d(x)))):
    for j in q:
        plan[f"{p}_{j}"] = f(q[j])
for j in q:
    plan[f"z_{j}"] = 1e-4 * np.tanh(plan[f"qd_{j}"] / 0.01)
noise = lambda s: s * rng.standard_normal(t.size) * (1 + t)
plan.update(E_x=Ex, E_y=Ey, E_z=Ez, z_a=z_a,
            phi_ellipse=np.where(t == 0, 0.0, noise(3e-13)),
            phi_height=np.where(t == 0, 0.0, noise(1e-14)),
            phid_ellipse=noise(1e-11), phid_height=noise(1e-12),
            psi_dr=psi_dr, tau_drive=tau_drive)
Qc = {"psi1": -0.2 * np.sin(2 * psi1), "psi2": 4.0 + 0.8 * np.sin(psi1) ** 2,
      "z3": -9.0 + 2.0 * np.cos(2 * psi1)}
for j in q:
    plan[f"Qc_{j}"] = Qc[j]
plan["required_psi1"] = tau_drive + Qc["psi1"]
plan["required_psi2"] = Qc["psi2"]
plan["required_z3"] = Qc["z3"]
write("plan.csv", plan)

delta = {"psi1": 40.0, "psi2": 3.0, "z3": 60.0}
kp = {"psi1": 400.0, "psi2": 400.0, "z3": 900.0}
kd = {"psi1": 40.0, "psi2": 40.0, "z3": 60.0}
runs = []
for friction in (False, True):
    for alpha in (45, 60, 70, 80):
        label = f"a{alpha}_{'friction' if friction else 'nofriction'}"
        q0 = {"psi1": 0.002 * (alpha - 45), "psi2": 1.5 * np.pi - math.radians(alpha), "z3": 0.5 + 2e-4 * (alpha - 45)}
        tr = {"t": t}
        for j in q:
            e0 = q0[j] - q[j][0]
            e = e0 * (1 + delta[j] * t) * np.exp(-delta[j] * t) + 1e-15 * rng.standard_normal(t.size)
            if friction:
                e += 2e-4 * np.tanh(plan[f"qd_{j}"] / 0.05) * (1 - np.exp(-5 * t))
            tr[f"e_{j}"] = e
            tr[f"q_{j}"] = q[j] + e
            tr[f"qref_{j}"] = q[j]
        for j in q:
            tr[f"qd_{j}"] = d(tr[f"q_{j}"])
        for j in q:
            tau = plan[f"required_{j}"] - kp[j] * tr[f"e_{j}"] - kd[j] * d(tr[f"e_{j}"])
            tr[f"tau_{j}"] = tau + (0.2 * np.tanh(plan[f"qd_{j}"] / 0.01) if friction else 0)
        tr["E_x"], tr["E_y"], tr["E_z"] = fk(tr["q_psi1"], tr["q_psi2"], tr["q_z3"])
        order = ["t"] + [f"{p}_{j}" for p in ("q", "qd", "qref", "e", "tau") for j in q] + \
                ["E_x", "E_y", "E_z"]
        write(f"track_{label}.csv", {k: tr[k] for k in order})
        runs.append({"label": label, "alpha0_deg": alpha, "plant_friction": friction})
with open(os.path.join(out, "summary.json"), "w") as f:
    json.dump({"runs": runs, "ellipse": {"a": a, "b": b}}, f, indent=1)
EOF

fail() { echo "plot_study_selftest: FAIL: $*" >&2; exit 1; }
names="fig4_drive fig5_end_effector fig6_joints fig7_errors fig7_errors_log fig8_torques
       fig8_torques_first_second fig9_friction fig10_plan"

"$PY" scripts/plot_study.py "$DIR" > "$DIR/written.txt"
for n in $names; do
  for ext in png pdf; do
    f="$DIR/figures/$n.$ext"
    [[ -s "$f" ]] || fail "$f not written"
    grep -qxF "$f" "$DIR/written.txt" || fail "$f not listed on stdout"
  done
  head -c 4 "$DIR/figures/$n.pdf" | grep -q '%PDF' || fail "$n.pdf is not a PDF"
done

# A missing column: one-line error naming file and column, exit 2, old figures untouched.
stamp=$(stat -c %Y.%s "$DIR/figures/fig6_joints.png")
bad="$DIR/bad"; mkdir -p "$bad"; cp "$DIR"/*.csv "$DIR"/summary.json "$bad"/
cp -rp "$DIR/figures" "$bad/"
sed -i '1s/,tau_z3,/,tau_zz,/' "$bad/track_a70_friction.csv"
set +e; err=$("$PY" scripts/plot_study.py "$bad" 2>&1 >/dev/null); rc=$?; set -e
[[ $rc -eq 2 ]] || fail "missing column: exit $rc, expected 2"
[[ $(printf '%s\n' "$err" | wc -l) -eq 1 ]] || fail "missing column: not one line: $err"
[[ "$err" == *track_a70_friction.csv*tau_z3* ]] || fail "missing column: unclear error: $err"
[[ $(stat -c %Y.%s "$bad/figures/fig6_joints.png") == "$stamp" ]] || fail "figure touched"
ls -A "$bad/figures" | grep -q '\.tmp$' && fail "temporary files left behind"

# A missing file listed in summary.json.
rm "$bad/track_a80_nofriction.csv"; sed -i '1s/,tau_zz,/,tau_z3,/' "$bad/track_a70_friction.csv"
set +e; err=$("$PY" scripts/plot_study.py "$bad" 2>&1 >/dev/null); rc=$?; set -e
[[ $rc -eq 2 && "$err" == *track_a80_nofriction.csv*"not found"* ]] || fail "missing file: $rc $err"

# Binary, non-UTF-8 and corrupted CSVs, broken summary.json: one line "refdyn: error: FILE: ...",
# exit 2, no traceback, old figures untouched.
cp "$DIR/track_a80_nofriction.csv" "$bad/"
cp "$bad/plan.csv" "$bad/plan.csv.good"; cp "$bad/summary.json" "$bad/summary.json.good"
check_bad() {  # FILE DESCRIPTION
  set +e; err=$("$PY" scripts/plot_study.py "$bad" 2>&1 >/dev/null); rc=$?; set -e
  [[ $rc -eq 2 ]] || fail "$2: exit $rc, expected 2: $err"
  [[ $(printf '%s\n' "$err" | wc -l) -eq 1 ]] || fail "$2: not one line: $err"
  [[ "$err" == "refdyn: error: $bad/$1"* ]] || fail "$2: unclear error: $err"
  [[ $(stat -c %Y.%s "$bad/figures/fig6_joints.png") == "$stamp" ]] || fail "$2: figure touched"
  if ls -A "$bad/figures" | grep -q '\.tmp$'; then fail "$2: temporary files left behind"; fi
}
head -c 3000 /dev/urandom > "$bad/plan.csv"; printf '\0' >> "$bad/plan.csv"; check_bad plan.csv "binary CSV"
{ printf 't,q_\xe9\n'; tail -n +2 "$bad/plan.csv.good"; } > "$bad/plan.csv"; check_bad plan.csv "non-UTF-8 CSV"
{ head -n 100 "$bad/plan.csv.good"; printf '0.1,abc\n'; } > "$bad/plan.csv"; check_bad plan.csv "corrupted CSV"
: > "$bad/plan.csv"; check_bad plan.csv "empty CSV"
cp "$bad/plan.csv.good" "$bad/plan.csv"
printf '{"runs": [' > "$bad/summary.json"; check_bad summary.json "truncated JSON"
printf '[1, 2]' > "$bad/summary.json"; check_bad summary.json "JSON not an object"
printf '{"runs": [{"label": "a45_nofriction", "alpha0_deg": "x", "plant_friction": false}], "ellipse": {"a": 1, "b": 1}}' \
  > "$bad/summary.json"; check_bad summary.json "alpha0_deg not a number"
printf '\xff\xfe{}' > "$bad/summary.json"; check_bad summary.json "non-UTF-8 JSON"
cp "$bad/summary.json.good" "$bad/summary.json"; rm "$bad/plan.csv.good" "$bad/summary.json.good"

# One more rendering (each takes ~40 s) checks two things: without summary.json (runs read from
# track_*.csv, one of them missing) the figures are still drawn, with a warning; and figures get
# mode 0666 minus the umask (027 here: 640).
rm "$bad/summary.json" "$bad/track_a80_friction.csv"; rm -rf "$bad/figures"
(umask 027; "$PY" scripts/plot_study.py "$bad" > /dev/null 2>"$bad/stderr.txt") ||
  fail "no summary.json, umask 027: $(cat "$bad/stderr.txt")"
[[ -s "$bad/figures/fig9_friction.png" ]] || fail "no summary.json: fig9 missing"
for f in "$bad"/figures/*; do
  [[ $(stat -c %a "$f") == 640 ]] || fail "$f: mode $(stat -c %a "$f"), expected 640 under umask 027"
done

echo "plot_study_selftest: OK ($(wc -l < "$DIR/written.txt") files in $DIR/figures)"
