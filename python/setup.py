"""Builds the extension with the project's CMake build (see pyproject.toml)."""
import os
import pathlib
import shutil
import subprocess
import sys

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext

ROOT = pathlib.Path(__file__).resolve().parent.parent


class CMakeBuild(build_ext):
    def build_extension(self, ext):
        build = pathlib.Path(os.environ.get("REFDYN_BUILD_DIR", ROOT / "build")).resolve()
        python = os.path.realpath(sys.executable)  # a venv's python: the interpreter it links to
        subprocess.run(["cmake", "-S", str(ROOT), "-B", str(build), "-DCMAKE_BUILD_TYPE=Release",
                        f"-DPython_EXECUTABLE={python}"], check=True)
        subprocess.run(["cmake", "--build", str(build), "-j", os.environ.get("REFDYN_JOBS", "2"),
                        "--target", "refdyn_python"], check=True)
        name = pathlib.Path(self.get_ext_filename(ext.name)).name
        dest = pathlib.Path(self.get_ext_fullpath(ext.name))
        dest.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(build / "python" / "refdyn" / name, dest)


setup(packages=["refdyn"], ext_modules=[Extension("refdyn._refdyn", sources=[])],
      cmdclass={"build_ext": CMakeBuild})
