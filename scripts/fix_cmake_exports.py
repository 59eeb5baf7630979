"""Point the CMake exports of the ROS message wheels at this machine's include directories.

The PyPI wheels of the ROS 2 message packages were built on a manylinux image; their
``export_*__rosidl_generator_pyExport.cmake`` files name that image's Python and NumPy include
directories (``/opt/python/cp311-cp311/...``). CMake refuses to configure a package that
depends on them while those paths do not exist. This rewrites the paths, in place and
idempotently, to the running interpreter's include directory and NumPy's include directory.
"""

from __future__ import annotations

import sys
import sysconfig
from pathlib import Path

import numpy

BUILD_PY_INCLUDE = "/opt/python/cp311-cp311/include/python3.11"
BUILD_NP_INCLUDE = "/opt/python/cp311-cp311/lib/python3.11/site-packages/numpy/_core/include"


def main() -> int:
    prefix = Path(sys.prefix)
    py_include = sysconfig.get_paths()["include"]
    np_include = numpy.get_include()
    if not Path(py_include, "Python.h").is_file():
        print(f"fix_cmake_exports: no Python.h in {py_include}", file=sys.stderr)
        return 1
    changed = 0
    for path in (prefix / "share").glob("*/cmake/*.cmake"):
        text = path.read_text()
        if BUILD_PY_INCLUDE not in text and BUILD_NP_INCLUDE not in text:
            continue
        text = text.replace(BUILD_NP_INCLUDE, np_include).replace(BUILD_PY_INCLUDE, py_include)
        path.write_text(text)
        changed += 1
    print(f"fix_cmake_exports: rewrote {changed} CMake export file(s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
