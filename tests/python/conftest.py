"""Shared fixtures of the Python tests. CTest sets PYTHONPATH (build/python), REFDYN_CLI (the
refdyn executable) and REFDYN_SOURCE_DIR; run by hand they default to the build folder `build`."""
import os
import pathlib
import sys

import pytest

SOURCE_DIR = pathlib.Path(os.environ.get("REFDYN_SOURCE_DIR", pathlib.Path(__file__).resolve().parents[2]))
BUILD_DIR = pathlib.Path(os.environ.get("REFDYN_BUILD_DIR", SOURCE_DIR / "build"))
if not any(pathlib.Path(p, "refdyn").is_dir() for p in sys.path if p):
    sys.path.insert(0, str(BUILD_DIR / "python"))

PAPER_YAML = SOURCE_DIR / "examples" / "paper" / "paper.yaml"
MINIMAL_YAML = SOURCE_DIR / "tests" / "data" / "good" / "minimal.yaml"
BAD_DIR = SOURCE_DIR / "tests" / "data" / "bad"


@pytest.fixture(scope="session")
def cli():
    path = pathlib.Path(os.environ.get("REFDYN_CLI", BUILD_DIR / "apps" / "refdyn"))
    if not path.is_file():
        pytest.fail(f"the refdyn executable is needed: {path} (build the target refdyn)")
    return path


@pytest.fixture(scope="session")
def paper_results():
    import refdyn
    return refdyn.run(PAPER_YAML)
