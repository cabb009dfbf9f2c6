#!/usr/bin/python3
"""CTest test doc_commands: the shell commands shown in README.md and docs/*.md run.

Every line of a fenced block marked bash, sh, shell or console (continuation lines joined,
comments dropped) is either RUN or SKIPPED by the explicit rules below; a line that matches
neither fails the test, so a new command in the docs is noticed.

RUN: commands starting with `refdyn` (the built binary, through PATH) and `/usr/bin/python3`
or `PYTHONPATH=... /usr/bin/python3` (only when the Python module is built: else reported as
skipped). Each document's commands run in order, in one temporary folder per document, in
which `examples`, `scripts` and `tests` link to the source tree; each must exit 0 within
its timeout. `export PYTHONPATH=...` lines set the variable for the following lines.

SKIPPED (with the reason printed): installs (apt-get, pip, venv, install-deps.sh), configure
and build steps (cmake), the long scripts (run.sh, test.sh, test-sanitizers.sh, fuzz.sh,
sweep_scaling.sh, .ci/run on a fresh clone), test runners (ctest, valgrind), benchmark and
fuzzer executables, and mpirun (tests/mpi_test.sh runs `track --mpi` when refdyn is built with MPI).

Usage: doc_commands_test.py SOURCE_DIR REFDYN [WORK_DIR]
"""
import os
import re
import shutil
import subprocess
import sys
import tempfile

FENCE = re.compile(r"^\s*```\s*([A-Za-z]*)")
SHELL_LANGS = {"bash", "sh", "shell", "console"}

# (regex on the command, reason): checked in order before RUN.
SKIP = [
    (r"(^|\s)bash scripts/(run|test|test-sanitizers|fuzz|install-deps)\.sh\b", "long script (installs, full builds, the whole suite)"),
    (r"^(REFDYN_\w+=\S+\s+|FUZZ_\w+=\S+\s+)+bash scripts/", "long script (installs, full builds, the whole suite)"),
    (r"^bash bench/sweep_scaling\.sh\b", "benchmark script (minutes of runs)"),
    (r"^git clone .*bash \.ci/run$", "the whole CI on a fresh clone (45 minutes)"),
    (r"^(sudo\s+)?apt-get\b", "install"),
    (r"^\S*pip install\b|^\S+/bin/pip\b", "install"),
    (r"-m venv\b|^~/venvs/", "install (virtual environment)"),
    (r"^(nice -n \d+ )?cmake\b", "configure/build/install step"),
    (r"^cd build && ctest\b|^ctest\b", "test runner (the suite itself)"),
    (r"^valgrind\b", "test runner (valgrind build)"),
    (r"^(\./)?build/bench/|^build-asan/fuzz/", "benchmark or fuzzer executable"),
    (r"^mpirun\b", "MPI launch (tests/mpi_test.sh runs track --mpi when built with MPI)"),
    (r"^(for|case|done|do)\b", "shell loop of the valgrind recipe"),
    (r"^\S+\s+\|\|\s+echo", "shell loop of the valgrind recipe"),
]
RUN = re.compile(r"^(refdyn\b|(PYTHONPATH=\S+\s+)?/usr/bin/python3\b|export PYTHONPATH=)")


def commands(path):
    """(line number, command) for each shell line of the document's fenced blocks."""
    out, lang, pending, start = [], None, "", 0
    with open(path, encoding="utf-8") as f:
        for n, line in enumerate(f, 1):
            m = FENCE.match(line)
            if m:
                lang = None if lang is not None else m.group(1).lower()
                continue
            if lang not in SHELL_LANGS:
                continue
            text = line.rstrip("\n")
            if not pending:
                start = n
            if text.rstrip().endswith("\\"):
                pending += text.rstrip()[:-1] + " "
                continue
            text = pending + text
            pending = ""
            # drop a trailing comment (a '#' after whitespace, outside quotes)
            cmd, quote = "", None
            for i, ch in enumerate(text):
                if quote:
                    quote = None if ch == quote else quote
                elif ch in "'\"":
                    quote = ch
                elif ch == "#" and (i == 0 or text[i - 1].isspace()):
                    break
                cmd += ch
            cmd = " ".join(cmd.split())
            if cmd:
                out.append((start, cmd))
    return out


def main():
    if len(sys.argv) < 3:
        print(__doc__)
        return 2
    src, refdyn = os.path.abspath(sys.argv[1]), os.path.abspath(sys.argv[2])
    work = os.path.abspath(sys.argv[3]) if len(sys.argv) > 3 else tempfile.mkdtemp(prefix="refdyn_doc_")
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    bindir = os.path.join(work, "bin")
    os.makedirs(bindir)
    os.symlink(refdyn, os.path.join(bindir, "refdyn"))
    build_python = os.path.join(os.path.dirname(os.path.dirname(refdyn)), "python")
    have_python = os.path.isdir(os.path.join(build_python, "refdyn")) and any(
        f.startswith("_refdyn") for f in os.listdir(os.path.join(build_python, "refdyn")))

    docs = [os.path.join(src, "README.md")] + sorted(
        os.path.join(src, "docs", f) for f in os.listdir(os.path.join(src, "docs")) if f.endswith(".md"))
    failures, ran, skipped = [], 0, 0
    for doc in docs:
        rel = os.path.relpath(doc, src)
        cwd = os.path.join(work, rel.replace("/", "_").replace(".md", ""))
        os.makedirs(cwd)
        for d in ("examples", "scripts", "tests"):
            os.symlink(os.path.join(src, d), os.path.join(cwd, d))
        env = dict(os.environ, PATH=bindir + os.pathsep + os.environ.get("PATH", ""))
        env.pop("PYTHONPATH", None)
        for line, cmd in commands(doc):
            where = f"{rel}:{line}"
            reason = next((r for pat, r in SKIP if re.search(pat, cmd)), None)
            if reason:
                print(f"skip {where}: {cmd}  ({reason})")
                skipped += 1
                continue
            if not RUN.match(cmd):
                failures.append(f"{where}: '{cmd}' is neither run nor skipped: add a rule to tests/doc_commands_test.py")
                continue
            if cmd.startswith("export PYTHONPATH="):
                env["PYTHONPATH"] = build_python  # $PWD/build/python of the docs: the build's package
                continue
            if not cmd.startswith("refdyn"):  # /usr/bin/python3 ..., PYTHONPATH=... /usr/bin/python3 ...
                if not have_python:
                    print(f"skip {where}: {cmd}  (the Python module is not built)")
                    skipped += 1
                    continue
                # PYTHONPATH=build/python of the docs: the build's package
                cmd = re.sub(r"^PYTHONPATH=\S+\s+", "", cmd)
                env["PYTHONPATH"] = build_python
            try:
                r = subprocess.run(["/bin/bash", "-c", cmd], cwd=cwd, env=env, capture_output=True, text=True,
                                   timeout=300)
            except subprocess.TimeoutExpired:
                failures.append(f"{where}: '{cmd}' did not finish within 300 s")
                continue
            ran += 1
            if r.returncode != 0:
                msg = (r.stderr.strip() or r.stdout.strip()).splitlines()
                failures.append(f"{where}: '{cmd}' exited {r.returncode}: {msg[-1] if msg else ''}")
            else:
                print(f"ok   {where}: {cmd}")
    for f in failures:
        print("FAIL " + f)
    print(f"doc_commands: {ran} run, {skipped} skipped, {len(failures)} failed")
    if ran == 0:
        print("FAIL no command was run")
        return 1
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
