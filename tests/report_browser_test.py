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
  4. A URDF model with visual meshes (tests/data/urdf: the 7-joint arm with a gripper, the 6-joint
     arm through ROS_PACKAGE_PATH): the page inlines the meshes and the loaders, the paper's does
     not; over --mesh-budget the page draws segments and the command says so; an unresolved
     package is a note. In the browser: no error, every item drawn; a screenshot
     (OUT/report_arm7_meshes.png) shows the meshes' colours.

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

# ---- 4. a URDF model drawn with its visual meshes (docs/report.md, "A URDF model's own shapes") ----
def page_data(path):
    m = re.search(r'<script type="application/json" id="refdyn-data">(.*?)</script>', open(path, encoding="utf-8").read(), re.S)
    return json.loads(m.group(1)) if m else {}


LOADERS = ("exports.STLLoader", "exports.OBJLoader", "exports.ColladaLoader")
check(not any(x in html for x in LOADERS), "the paper's page (no meshes) carries no mesh loader")
arm7 = os.path.join(OUT, "arm7")
r = run([REFDYN, "plan", os.path.join(SOURCE, "tests/data/urdf/arm7_hand.yaml"), "-o", arm7, "--report", "-q"])
check(r.returncode == 0 and r.stderr == "", "refdyn plan arm7_hand --report: exit 0, no note (%d: %s)" % (r.returncode, r.stderr.strip()))
arm7_html = os.path.join(arm7, "report.html")
arm7_page = open(arm7_html, encoding="utf-8").read()
vis = page_data(arm7_html)["scenario"]["visuals"]
print("arm7_hand page: %.2f MB, %d meshes (%d bytes of base64) for %d visual items" %
      (len(arm7_page) / 1e6, len(vis["meshes"]), vis["bytes"], len(vis["items"])))
check(len(vis["items"]) == 13 and len(vis["meshes"]) == 10 and not vis["fallback"] and vis["notes"] == [],
      "arm7_hand page: 13 visual items (11 meshes in 10 files, a box, a sphere), no note")
check(all(x in arm7_page for x in LOADERS), "arm7_hand page: the STL, OBJ and COLLADA loaders are inlined")
sticks = os.path.join(OUT, "arm7_sticks.html")
r = run([REFDYN, "report", arm7, "--mesh-budget", "0.001", "-o", sticks])
vs = page_data(sticks).get("scenario", {}).get("visuals", {})
check(r.returncode == 0 and "report: note: the URDF's meshes (" in r.stderr and "exceed the report's budget of 0.001 MB" in r.stderr
      and vs.get("fallback") is True and vs.get("items") == [] and not any(x in open(sticks).read() for x in LOADERS),
      "over the mesh budget: a note on stderr, segments, no loader in the page (%s)" % r.stderr.strip())
arm6 = os.path.join(OUT, "arm6")
env = dict(os.environ, ROS_PACKAGE_PATH=os.path.join(SOURCE, "tests/data/urdf"))
r = run([REFDYN, "track", os.path.join(SOURCE, "tests/data/urdf/arm6.yaml"), "-o", arm6, "--report", "-q"], env=env)
v6 = page_data(os.path.join(arm6, "report.html")).get("scenario", {}).get("visuals", {})
check(r.returncode == 0 and r.stderr == "" and len(v6.get("items", [])) == 8 and v6.get("notes") == [],
      "arm6 with ROS_PACKAGE_PATH: 7 meshes and a cylinder, no note (%d: %s)" % (r.returncode, r.stderr.strip()))
env.pop("ROS_PACKAGE_PATH")
arm6_bare = os.path.join(OUT, "arm6_no_package")
r = run([REFDYN, "plan", os.path.join(SOURCE, "tests/data/urdf/arm6.yaml"), "-o", arm6_bare, "--report"], env=env)
vb = page_data(os.path.join(arm6_bare, "report.html")).get("scenario", {}).get("visuals", {})
check(r.returncode == 0 and "package 'refdyn_test_arm' is not known" in r.stderr and "4 more notes" in r.stderr
      and len(vb.get("items", [])) == 1 and len(vb.get("notes", [])) == 7,
      "arm6 without the package: exit 0, notes on stderr and in the page, the primitive drawn (%d: %s)" % (r.returncode, r.stderr.strip()))

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

# ---- 5. the meshes in the browser ----
def selftest_of(path, t):
    r = chromium("file://" + path + "#selftest=%g" % t, "--dump-dom")
    m = re.search(r'<pre id="selftest"[^>]*>([^<]*)</pre>', r.stdout)
    return json.loads(m.group(1)) if m and m.group(1).strip() else {"errors": ["no self-test output"]}


s7 = selftest_of(arm7_html, 1.0)
print("arm7_hand self-test:", json.dumps({k: s7.get(k) for k in ("errors", "meshes", "canvas3d")}))
m7 = s7.get("meshes") or {}
check(s7["errors"] == [] and m7.get("drawn") == 13 and m7.get("items") == 13 and m7.get("failed") == [],
      "arm7_hand page in the browser: no error, every visual item drawn, none failed")
c7 = s7.get("canvas3d", {})
check(c7.get("nonBackgroundPixels", 0) / max(1, c7.get("width", 0) * c7.get("height", 0)) > 0.05,
      "arm7_hand page: the 3D canvas is drawn")
ss = selftest_of(sticks, 1.0)
check(ss["errors"] == [] and (ss.get("meshes") or {}).get("fallback") is True,
      "the page over the budget: no error, segments (%s)" % ss["errors"])
s6 = selftest_of(os.path.join(arm6, "report.html"), 1.0)
check(s6["errors"] == [] and (s6.get("meshes") or {}).get("drawn") == 8, "arm6 page: no error, 8 items drawn (%s)" % s6["errors"])
sb = selftest_of(os.path.join(arm6_bare, "report.html"), 1.0)
check(sb["errors"] == [] and (sb.get("meshes") or {}).get("drawn") == 1, "arm6 page without the package: no error, the cylinder drawn")
shot7 = os.path.join(OUT, "report_arm7_meshes.png")
r = chromium("file://" + arm7_html + "#selftest=1", "--screenshot=" + shot7)
check(r.returncode == 0 and os.path.exists(shot7), "screenshot written: " + shot7)
if Image and os.path.exists(shot7):
    img = Image.open(shot7).convert("RGB")
    dpr = s7.get("devicePixelRatio", 1)
    x, y, w, h = (int(round(v * dpr)) for v in s7["rects"]["canvas3d"])
    c = img.crop((x + 2, y + 2, x + w - 2, y + h - 2))
    px = list(c.getdata())
    # the COLLADA links' own orange (0.95, 0.45, 0.05) and the STL/OBJ links' URDF grey (0.55, 0.57, 0.6), shaded
    orange = sum(1 for p in px if p[0] > 120 and 0.3 * p[0] < p[1] < 0.7 * p[0] and p[2] < 0.25 * p[0])
    grey = sum(1 for p in px if 60 < p[0] < 215 and abs(p[0] - p[1]) < 12 and 0 <= p[2] - p[0] < 20)
    print("screenshot %s: %d orange and %d grey pixels of %d in the 3D canvas" % (shot7, orange, grey, len(px)))
    check(orange > 2000, "screenshot: the COLLADA links' orange is visible")
    check(grey > 5000, "screenshot: the STL and OBJ links' grey is visible")

shutil.rmtree(os.path.join(OUT, "chromium-profile"), ignore_errors=True)
if failures:
    print("%d check(s) failed" % len(failures))
    sys.exit(1)
print("all checks passed")
