# Sourced by the Python package's and the Blender add-on's test runners, after they set `python` and
# `package`: exits 77 (ctest's SKIP_RETURN_CODE) naming what is missing: python3, numpy, or the
# package's modules (FACEMORPH_PYTHON found no pybind11, or was off).
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
