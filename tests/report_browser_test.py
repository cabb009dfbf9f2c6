#!/usr/bin/env python3
"""Browser test of `refdyn report` (docs/report.md): the paper study's report.html in headless
Chromium (Debian `chromium`, WebGL by SwiftShader, every host name unresolvable so that nothing
can be fetched).

  1. `refdyn paper -o OUT/paper --report` writes report.html: < 5 MB, no external resource;
     `refdyn report OUT/paper` writes the same bytes from the files; bad input is one line
     "refdyn: error: ..." with exit 2 and writes nothing; `refdyn report` of a `refdyn plan`
     folder finds the scenario through summary.json or --scenario (and that page has no error).
  2. The page opened with #selftest=2.5 (the replay scrubbed to t = 2.5 s) writes its own check
     into <pre id="selftest">, read with --dump-dom: no error (window.onerror, unhandled
     rejections and console.error are recorded from the first script on), WebGL works, every
     plot has ink, the 3D canvas is not blank, and the end-effector drawn in the replay is the
     plan's E(2.5) from plan.csv.
  3. A screenshot (1400 x 1000, kept as OUT/report_paper_t2.5.png) has ink in the 3D canvas and
     in the first plot, and the end-effector's colour in the canvas.

Exit 77 (CTest: skipped) when chromium is not installed. Usage:
  report_browser_test.py REFDYN OUT
"""
import json
import math
import os
import re
import shutil
import subprocess
import sys

REFDYN, OUT = sys.argv[1], os.path.abspath(sys.argv[2])
CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
failures = []


def check(ok, what):
    print(("ok    " if ok else "FAIL  ") + what, flush=True)
    if not ok:
        failures.append(what)


def run(args, **kw):
    return subprocess.run(args, capture_output=True, text=True, timeout=600, **kw)


def chromium(url, *extra):
    args = [CHROMIUM, "--headless=new", "--no-sandbox", "--disable-gpu", "--use-angle=swiftshader",
            "--enable-unsafe-swiftshader", "--disable-dev-shm-usage", "--window-size=1400,1000", "--hide-scrollbars",
            "--host-resolver-rules=MAP * ~NOTFOUND", "--no-first-run", "--disable-extensions",
            "--user-data-dir=" + os.path.join(OUT, "chromium-profile"),
            "--run-all-compositor-stages-before-draw", "--virtual-time-budget=20000", *extra, url]
    return run(args)


shutil.rmtree(OUT, ignore_errors=True)
os.makedirs(OUT)
paper = os.path.join(OUT, "paper")

# ---- 1. the report file ----
r = run([REFDYN, "paper", "-o", paper, "--report", "-q"])
check(r.returncode == 0, "refdyn paper --report exits 0 (%d: %s)" % (r.returncode, r.stderr.strip()))
html_path = os.path.join(paper, "report.html")
size = os.path.getsize(html_path)
print("report.html of the paper study: %d bytes (%.2f MB)" % (size, size / 1e6))
check(size < 5_000_000, "report.html < 5 MB")
html = open(html_path, encoding="utf-8").read()
external = re.findall(r"<(?:script|link|img|iframe|source)\b[^>]*\b(?:src|href)\s*=", html)
check(not external, "no element loads an external resource (%s)" % external[:3])
again = os.path.join(OUT, "again.html")
r = run([REFDYN, "report", paper, "-o", again, "-q"])
check(r.returncode == 0 and open(again, encoding="utf-8").read() == html,
      "refdyn report DIR writes the same report from the files (%s)" % r.stderr.strip())

bad = os.path.join(OUT, "bad")
os.makedirs(bad)
for f in ("plan.csv", "summary.json", "feasibility.json"):
    shutil.copy(os.path.join(paper, f), bad)
with open(os.path.join(bad, "plan.csv"), "a") as f:
    f.write("1,2,oops\n")
r = run([REFDYN, "report", bad])
lines = r.stderr.strip().splitlines()
check(r.returncode == 2 and len(lines) == 1 and lines[0].startswith("refdyn: error: ") and "plan.csv:5003" in lines[0]
      and not os.path.exists(os.path.join(bad, "report.html")),
      "a corrupted plan.csv: one line, exit 2, nothing written (%d: %s)" % (r.returncode, r.stderr.strip()))
r = run([REFDYN, "report", os.path.join(OUT, "no-such-folder")])
check(r.returncode == 2 and r.stderr.startswith("refdyn: error: ") and r.stderr.count("\n") == 1,
      "a missing folder: one line, exit 2 (%s)" % r.stderr.strip())
r = run([REFDYN, "report", paper, "--scenario", os.path.join(OUT, "none.yaml"), "-o", os.path.join(OUT, "x.html")])
check(r.returncode == 2 and r.stderr.count("\n") == 1 and not os.path.exists(os.path.join(OUT, "x.html")),
      "a missing --scenario: one line, exit 2, nothing written (%s)" % r.stderr.strip())

# A scenario file's results: `refdyn report DIR` finds the scenario through summary.json's "file"
# (relative to where refdyn ran), or needs --scenario.
SOURCE = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
planar = os.path.join(OUT, "planar")
r = run([REFDYN, "plan", "examples/planar_2r_circle/planar_2r_circle.yaml", "-o", planar, "-q"], cwd=SOURCE)
check(r.returncode == 0, "refdyn plan planar_2r_circle (%s)" % r.stderr.strip())
r = run([REFDYN, "report", planar, "-q"], cwd=SOURCE)
check(r.returncode == 0 and os.path.exists(os.path.join(planar, "report.html")),
      "refdyn report finds the scenario named in summary.json (%s)" % r.stderr.strip())
os.remove(os.path.join(planar, "report.html"))
r = run([REFDYN, "report", planar, "-q"], cwd=OUT)
check(r.returncode == 2 and "--scenario" in r.stderr and r.stderr.count("\n") == 1
      and not os.path.exists(os.path.join(planar, "report.html")),
      "from elsewhere: one line with the --scenario hint, exit 2, nothing written (%s)" % r.stderr.strip())
r = run([REFDYN, "report", planar, "-q", "--scenario",
         os.path.join(SOURCE, "examples/planar_2r_circle/planar_2r_circle.yaml")], cwd=OUT)
check(r.returncode == 0 and os.path.exists(os.path.join(planar, "report.html")), "with --scenario (%s)" % r.stderr.strip())

# The 3D view's "up" is against gravity: the four-bar (gravity along -y) stands in the x-y
# plane, the paper's manipulator (gravity along -z) has +z up. Written into the page's data.
def page_up(path):
    m = re.search(r'"gravity":\[[^\]]*\],"up":\[([^\]]*)\]', open(path, encoding="utf-8").read())
    return [float(x) for x in m.group(1).split(",")] if m else None


four_bar = os.path.join(OUT, "four_bar")
r = run([REFDYN, "plan", "examples/four_bar/four_bar.yaml", "-o", four_bar, "-q", "--report"], cwd=SOURCE)
check(r.returncode == 0, "refdyn plan four_bar --report (%s)" % r.stderr.strip())
four_bar_html = os.path.join(four_bar, "report.html")
check(page_up(four_bar_html) == [0.0, 1.0, 0.0], "four-bar page: up = -gravity direction = [0, 1, 0] (%s)" % page_up(four_bar_html))
check(page_up(html_path) == [0.0, 0.0, 1.0], "paper page: up = [0, 0, 1] (%s)" % page_up(html_path))

if not CHROMIUM:
    print("SKIP: chromium not installed (bash scripts/install-deps.sh installs it)")
    sys.exit(77 if not failures else 1)

# ---- 2. the page checks itself at t = 2.5 s ----
T = 2.5
url = "file://" + html_path + "#selftest=%g" % T
r = chromium(url, "--dump-dom")
m = re.search(r'<pre id="selftest"[^>]*>([^<]*)</pre>', r.stdout)
check(m is not None and m.group(1).strip() != "", "the page ran its self-test (chromium exit %d)" % r.returncode)
if m is None or not m.group(1).strip():
    print(r.stderr[-3000:])
    sys.exit(1)
st = json.loads(m.group(1))
print("self-test:", json.dumps({k: v for k, v in st.items() if k != "plotPixels"}))
check(st["errors"] == [], "no error in the page: %s" % st["errors"])
check(st["webgl"], "WebGL context created")
check(st["graphs"] >= 20, "at least 20 plots (%d)" % st["graphs"])
check(st["plotsInked"] == st["graphs"], "every plot has ink (%d of %d)" % (st["plotsInked"], st["graphs"]))
c3 = st.get("canvas3d", {})
frac = c3.get("nonBackgroundPixels", 0) / max(1, c3.get("width", 0) * c3.get("height", 0))
check(frac > 0.02, "the 3D canvas is drawn (%.1f %% of its pixels differ from the background)" % (100 * frac))

# E from plan.csv (full rate)
rows = [line.split(",") for line in open(os.path.join(paper, "plan.csv")).read().split("\n") if line]
head = rows[0]
data = [[float(x) for x in row] for row in rows[1:]]
ix, iy, iz = head.index("E_x"), head.index("E_y"), head.index("E_z")
t = [row[0] for row in data]
k = min(range(len(t)), key=lambda i: abs(t[i] - T))
check(abs(t[k] - T) < 1e-12, "plan.csv has a sample at t = %g s" % T)
E = [data[k][ix], data[k][iy], data[k][iz]]
ee = st["endEffector"]
drawn = [ee["x"], ee["y"], ee["z"]]
err = math.sqrt(sum((a - b) ** 2 for a, b in zip(drawn, E)))
# The replay interpolates linearly between frames t_a, t_b (every k-th sample): the drawn E must
# be that interpolation of plan.csv's E to the 7 significant digits the report stores (rounding
# 5e-7 |x| per coordinate), and so E(2.5) within the chord error max|E''| (t_b - t_a)^2 / 8
# (E'' from second differences of plan.csv) plus that rounding.
ta, tb = ee["frame"]
ka, kb = t.index(min(t, key=lambda s: abs(s - ta))), t.index(min(t, key=lambda s: abs(s - tb)))
w = (T - t[ka]) / (t[kb] - t[ka]) if kb > ka else 0.0
lerp = [data[ka][c] + w * (data[kb][c] - data[ka][c]) for c in (ix, iy, iz)]
err_lerp = math.sqrt(sum((a - b) ** 2 for a, b in zip(drawn, lerp)))
acc = 0.0
for i in range(max(1, ka - 1), min(len(t) - 1, kb + 2)):
    h = t[i + 1] - t[i]
    acc = max(acc, math.sqrt(sum(((data[i + 1][c] - 2 * data[i][c] + data[i - 1][c]) / h ** 2) ** 2 for c in (ix, iy, iz))))
rounding = 5e-7 * math.sqrt(sum(x * x for x in E)) + 1e-12
bound = acc * (t[kb] - t[ka]) ** 2 / 8 + rounding
print("E(2.5) in plan.csv: %s; drawn in the replay: %s" % (E, drawn))
print("|drawn - E(2.5)| = %.3e m (bound %.3e m: max|E''| = %.3f m/s^2 over frames %.4f..%.4f s); "
      "|drawn - interpolated plan.csv| = %.3e m" % (err, bound, acc, ta, tb, err_lerp))
check(ee["point"] == "E" and abs(ee["t"] - T) < 1e-12, "the replay is at t = %g s with end-effector E" % T)
check(err_lerp < rounding, "the drawn end-effector is plan.csv's E interpolated between the replay frames")
check(err < bound, "the drawn end-effector is at the plan's E(2.5) within the interpolation bound")

# The planar arm's report (no experiments, a circle at constant speed) also runs without error.
r = chromium("file://" + os.path.join(planar, "report.html") + "#selftest=1", "--dump-dom")
m2 = re.search(r'<pre id="selftest"[^>]*>([^<]*)</pre>', r.stdout)
st2 = json.loads(m2.group(1)) if m2 and m2.group(1).strip() else {"errors": ["no self-test output"], "graphs": 0, "plotsInked": -1}
check(st2["errors"] == [] and st2["graphs"] > 0 and st2["plotsInked"] == st2["graphs"],
      "planar_2r_circle report: no error, every plot inked (%s)" % st2["errors"])

# The view itself: the camera's up and the ground grid's normal follow gravity.
def close(a, b):
    return a is not None and len(a) == 3 and all(abs(x - y) < 1e-12 for x, y in zip(a, b))


check(close(st.get("view", {}).get("cameraUp"), [0, 0, 1]) and close(st.get("view", {}).get("gridNormal"), [0, 0, 1]),
      "paper page: camera up and ground normal +z (%s)" % st.get("view"))
r = chromium("file://" + four_bar_html + "#selftest=1", "--dump-dom")
m3 = re.search(r'<pre id="selftest"[^>]*>([^<]*)</pre>', r.stdout)
st3 = json.loads(m3.group(1)) if m3 and m3.group(1).strip() else {"errors": ["no self-test output"]}
check(st3["errors"] == [] and close(st3.get("view", {}).get("cameraUp"), [0, 1, 0])
      and close(st3.get("view", {}).get("gridNormal"), [0, 1, 0]),
      "four-bar page: no error, camera up and ground normal +y, against gravity (%s, %s)" % (st3["errors"], st3.get("view")))

# ---- 3. screenshot ----
shot = os.path.join(OUT, "report_paper_t2.5.png")
r = chromium(url, "--screenshot=" + shot)
check(r.returncode == 0 and os.path.exists(shot), "screenshot written: " + shot)
try:
    from PIL import Image
except ImportError:
    Image = None
    check(False, "python3-pil is installed (bash scripts/install-deps.sh)")
if Image and os.path.exists(shot):
    img = Image.open(shot).convert("RGB")
    dpr = st.get("devicePixelRatio", 1)

    def region(rect):
        x, y, w, h = (int(round(v * dpr)) for v in rect)
        return img.crop((x + 2, y + 2, x + w - 2, y + h - 2))

    def ink(im, bg, tol=30):
        px = list(im.getdata())
        return sum(1 for p in px if sum(abs(a - b) for a, b in zip(p, bg)) > tol) / max(1, len(px))

    c = region(st["rects"]["canvas3d"])
    f3 = ink(c, (245, 247, 250))
    magenta = sum(1 for p in c.getdata() if abs(p[0] - 230) < 40 and p[1] < 60 and abs(p[2] - 126) < 50)
    p1 = region(st["rects"]["firstPlot"])
    fp = ink(p1, (255, 255, 255))
    print("screenshot %s: 3D canvas %.1f %% ink, %d end-effector pixels; first plot %.1f %% ink" % (shot, 100 * f3, magenta, 100 * fp))
    check(f3 > 0.02, "screenshot: the 3D canvas is not blank")
    check(magenta > 20, "screenshot: the end-effector marker is visible")
    check(fp > 0.02, "screenshot: the first plot is not blank")

shutil.rmtree(os.path.join(OUT, "chromium-profile"), ignore_errors=True)
if failures:
    print("%d check(s) failed" % len(failures))
    sys.exit(1)
print("all checks passed")
