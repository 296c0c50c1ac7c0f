#!/bin/sh
# Runs one of the Python package's tests: run.sh PYTHON PACKAGE_DIR TEST.py [ARGS...]. Skips (exit
# 77, ctest's SKIP_RETURN_CODE) naming what is missing: python3, numpy, or the package's modules
# (FACEMORPH_PYTHON found no pybind11, or was off).
python=$1 package=$2 script=$3
shift 3
. "$(dirname "$0")/skip_without_package.sh"
PYTHONPATH="$package${PYTHONPATH:+:$PYTHONPATH}" exec "$python" "$script" "$@"
