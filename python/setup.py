"""Builds and installs the facemorph Python package from this checkout, offline:

    pip install --no-build-isolation ./python        (from the checkout's root)

with Debian's python3-setuptools, python3-pybind11 (pybind11-dev) and python3-numpy, and the
library's build dependencies (tools/install-deps.sh). The extension modules are built by the
project's own CMake (the option FACEMORPH_PYTHON=ON, no tools or tests) for the interpreter running
pip, in the checkout's build-python/ (kept, so that a second install rebuilds only what changed),
then copied into the package. FACEMORPH_CMAKE_ARGS adds CMake options (e.g.
"-DFACEMORPH_BUILD_ENCODER=OFF" for a decoder-only package without OpenCV). Where ccache is
installed it compiles, with the checkout as its base folder, so that objects the checkout's build/
already compiled are not compiled again. See spec/python.md.
"""

import os
import shlex
import shutil
import subprocess
import sys

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)


def version():
    # The project's version, where the build reads it: facemorph.h's FACEMORPH_VERSION_* (one number).
    parts = {}
    with open(os.path.join(ROOT, "codec", "decoder", "include", "facemorph.h")) as f:
        for line in f:
            words = line.split()
            if len(words) == 3 and words[0] == "#define" and words[1] in (
                    "FACEMORPH_VERSION_MAJOR", "FACEMORPH_VERSION_MINOR", "FACEMORPH_VERSION_PATCH"):
                parts[words[1]] = words[2]
    if len(parts) != 3:
        raise RuntimeError("facemorph: facemorph.h lacks FACEMORPH_VERSION_MAJOR, _MINOR or _PATCH")
    return ".".join(parts["FACEMORPH_VERSION_" + p] for p in ("MAJOR", "MINOR", "PATCH"))


class CMakeBuild(build_ext):
    def build_extensions(self):
        # Beside build/ (same depth): the same compile commands, so ccache finds build/'s objects.
        build = os.path.join(ROOT, "build-python")
        os.makedirs(build, exist_ok=True)
        args = ["-S", ROOT, "-B", build, "-DCMAKE_BUILD_TYPE=Release", "-DFACEMORPH_PYTHON=ON", "-DFACEMORPH_BUILD_TOOLS=OFF",
                "-DFACEMORPH_BUILD_TESTS=OFF", "-DFACEMORPH_SHARED=OFF", "-DFACEMORPH_INSTALL=OFF", f"-DPython_EXECUTABLE={sys.executable}"]
        if shutil.which("ninja"):
            args += ["-G", "Ninja"]
        env = dict(os.environ)
        if shutil.which("ccache"):
            args += ["-DCMAKE_CXX_COMPILER_LAUNCHER=ccache", "-DCMAKE_C_COMPILER_LAUNCHER=ccache"]
            # As tools/quickstart.sh sets them: the checkout's cache, paths relative to the checkout.
            env.setdefault("CCACHE_DIR", os.path.join(ROOT, "build-ccache"))
            env.setdefault("CCACHE_BASEDIR", ROOT)
            env.setdefault("CCACHE_SLOPPINESS", "pch_defines,time_macros,include_file_mtime,include_file_ctime")
        args += shlex.split(os.environ.get("FACEMORPH_CMAKE_ARGS", ""))
        subprocess.run(["cmake", *args], check=True, env=env)
        jobs = str(self.parallel or os.cpu_count() or 2)
        subprocess.run(["cmake", "--build", build, "--target", "facemorph_python", "-j", jobs], check=True, env=env)
        built = os.path.join(build, "python", "facemorph")
        for ext in list(self.extensions):
            name = ext.name.split(".")[-1]
            found = [f for f in os.listdir(built) if f.startswith(name + ".") and f.endswith(".so")]
            if not found:
                # The encoder's module is built only with the encoder (FACEMORPH_BUILD_ENCODER).
                if name == "_encoder":
                    print("facemorph: no encoder module in this build: facemorph.encode will say so", file=sys.stderr)
                    self.extensions.remove(ext)
                    continue
                raise RuntimeError(f"facemorph: {name} was not built in {built}")
            target = self.get_ext_fullpath(ext.name)
            os.makedirs(os.path.dirname(target), exist_ok=True)
            shutil.copyfile(os.path.join(built, found[0]), target)


setup(
    name="facemorph",
    version=version(),
    description="Compressed 3D facial video: decode any time t into numpy arrays, encode captures",
    long_description=open(os.path.join(HERE, "README.md")).read(),
    long_description_content_type="text/markdown",
    license="see the repository",
    packages=["facemorph"],
    package_data={"facemorph": ["*.pyi", "py.typed"]},
    ext_modules=[Extension("facemorph._decoder", sources=[]), Extension("facemorph._encoder", sources=[])],
    cmdclass={"build_ext": CMakeBuild},
    python_requires=">=3.8",
    install_requires=["numpy"],
    zip_safe=False,
)
