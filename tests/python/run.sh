#!/bin/sh
# Runs one of the Python package's tests: run.sh PYTHON PACKAGE_DIR TEST.py [ARGS...]. Skips (exit
# 77, ctest's SKIP_RETURN_CODE) naming what is missing: python3, numpy, or the package's modules
# (FACEMORPH_PYTHON found no pybind11, or was off).
python=$1 package=$2 script=$3
shift 3
if [ -z "$python" ] || ! command -v "$python" >/dev/null 2>&1; then
  echo "SKIP: no python3 (the Python package was not configured: see cmake's 'facemorph: the Python package' line)"
  exit 77
fi
if ! "$python" -c "import numpy" >/dev/null 2>&1; then
  echo "SKIP: $python cannot import numpy (Debian: python3-numpy)"
  exit 77
fi
if ! ls "$package"/facemorph/_decoder*.so >/dev/null 2>&1; then
  echo "SKIP: the facemorph Python modules are not built in $package (FACEMORPH_PYTHON; pybind11-dev, python3-pybind11)"
  exit 77
fi
PYTHONPATH="$package${PYTHONPATH:+:$PYTHONPATH}" exec "$python" "$script" "$@"
