#!/usr/bin/env python3
"""The source tree's layers (README, "Architecture"): a file includes only files of its own
layer or of layers below it, and the include graph has no cycle.

Layers, low to high (include/refdyn/<layer>/ and src/<layer>/; apps/ is the top):
  common, expression, multibody, constraints, forces, reference, simulate, models, scenario,
  symbolic, io, optimize, report, umbrella (include/refdyn/refdyn.hpp), apps

Usage: layers_test.py [SOURCE_DIR]   (default: the repository this file is in)
Exit 0 when the graph is clean; otherwise one line per violation and exit 1. A self-check runs
first: a made-up tree with an upward include and a cycle must be caught.
"""
import os
import re
import sys
import tempfile

LAYERS = ["common", "expression", "multibody", "constraints", "forces", "reference", "simulate", "models",
          "scenario", "symbolic", "io", "optimize", "report", "umbrella", "apps"]
RANK = {name: i for i, name in enumerate(LAYERS)}
INCLUDE = re.compile(r'^\s*#\s*include\s*"([^"]+)"', re.M)
SOURCE_ENDINGS = (".hpp", ".cpp", ".h", ".def")


def layer_of(rel):
    """The layer of a repository-relative path, or None for files outside the layered tree."""
    parts = rel.split("/")
    if parts[:2] == ["include", "refdyn"] and len(parts) == 3:  # include/refdyn/refdyn.hpp: everything
        return "umbrella"
    if parts[0] == "include" and len(parts) >= 4 and parts[1] == "refdyn":
        return parts[2]
    if parts[0] == "src" and len(parts) >= 3:
        return parts[1]
    if parts[0] == "apps":
        return "apps"
    return "(top level of " + "/".join(parts[:-1]) + ")"


def collect(root):
    files = []
    for top in ("include", "src", "apps"):
        for d, _, names in os.walk(os.path.join(root, top)):
            for n in names:
                if n.endswith(SOURCE_ENDINGS):
                    files.append(os.path.relpath(os.path.join(d, n), root).replace(os.sep, "/"))
    return sorted(files)


def resolve(root, rel, target):
    """The repository-relative path an #include "target" in file rel refers to, or None (system/external)."""
    here = os.path.dirname(rel)
    for cand in (os.path.join(here, target), os.path.join("include", target)):
        path = os.path.normpath(cand).replace(os.sep, "/")
        if os.path.isfile(os.path.join(root, path)):
            return path
    return None


def check(root):
    files = collect(root)
    graph, problems = {}, []
    for rel in files:
        with open(os.path.join(root, rel), encoding="utf-8", errors="replace") as f:
            text = f.read()
        deps = []
        for target in INCLUDE.findall(text):
            dep = resolve(root, rel, target)
            if dep is None:
                if target.startswith("refdyn/"):
                    problems.append(f"{rel}: includes \"{target}\", which does not exist")
                continue
            deps.append(dep)
            a, b = layer_of(rel), layer_of(dep)
            if a not in RANK:
                problems.append(f"{rel}: outside the layer folders {LAYERS}")
            elif b not in RANK:
                problems.append(f"{dep}: outside the layer folders (included by {rel})")
            elif RANK[b] > RANK[a]:
                problems.append(f"{rel}: upward include of {dep} (layer '{a}' may include only "
                                f"{', '.join(LAYERS[:RANK[a] + 1])})")
            if rel.startswith("include/") and dep.startswith("src/"):
                problems.append(f"{rel}: a public header includes the internal {dep}")
        graph[rel] = deps
    # cycles: iterative DFS with colours
    colour, stack_path = {}, []
    for start in files:
        if colour.get(start):
            continue
        stack = [(start, iter(graph.get(start, [])))]
        colour[start] = 1
        stack_path.append(start)
        while stack:
            node, it = stack[-1]
            nxt = next(it, None)
            if nxt is None:
                colour[node] = 2
                stack.pop()
                stack_path.pop()
                continue
            c = colour.get(nxt, 0)
            if c == 1:
                cyc = stack_path[stack_path.index(nxt):] + [nxt]
                problems.append("include cycle: " + " -> ".join(cyc))
            elif c == 0:
                colour[nxt] = 1
                stack.append((nxt, iter(graph.get(nxt, []))))
                stack_path.append(nxt)
    return files, problems


def self_check():
    with tempfile.TemporaryDirectory() as d:
        def put(rel, text):
            p = os.path.join(d, rel)
            os.makedirs(os.path.dirname(p), exist_ok=True)
            with open(p, "w") as f:
                f.write(text)
        put("include/refdyn/multibody/a.hpp", '#include "refdyn/simulate/b.hpp"\n')
        put("include/refdyn/simulate/b.hpp", '#include "refdyn/simulate/c.hpp"\n')
        put("include/refdyn/simulate/c.hpp", '#include "refdyn/simulate/b.hpp"\n')
        put("src/multibody/a.cpp", '#include "refdyn/multibody/a.hpp"\n#include <vector>\n')
        _, problems = check(d)
        assert any("upward include" in p and "a.hpp" in p for p in problems), problems
        assert any(p.startswith("include cycle") for p in problems), problems
        assert not any("src/multibody/a.cpp" in p for p in problems), problems


def main():
    root = sys.argv[1] if len(sys.argv) > 1 else os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    self_check()
    files, problems = check(root)
    for p in problems:
        print("layers: " + p)
    print(f"layers: {len(files)} files, {len(problems)} problem(s)")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
