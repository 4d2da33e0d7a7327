"""pip install --no-build-isolation .  (or ./build.sh python)

Builds the Python package `bootsurf` (python/bootsurf) for this python3 with
Debian's python3-dev, python3-numpy and python3-setuptools: the extension
bootsurf._core is compiled together with the library's sources (src/), with
the flags of the CMake build (C11, POSIX, OpenMP, -O3, hidden visibility),
and linked with libpng. No other package index is needed.
"""
import glob
import os
import re

import numpy
from setuptools import Extension, setup

ROOT = os.path.dirname(os.path.abspath(__file__))


def version():
    with open(os.path.join(ROOT, "include", "bootsurf.h")) as f:
        return re.search(r'#define BSURF_VERSION_STRING "([^"]+)"', f.read()).group(1)


def rel(p):
    return os.path.relpath(p, ROOT)


sources = [rel(os.path.join(ROOT, "python", "bootsurf", "_core.c"))] + sorted(
    rel(p) for p in glob.glob(os.path.join(ROOT, "src", "**", "*.c"), recursive=True))

core = Extension(
    "bootsurf._core",
    sources=sources,
    include_dirs=[rel(os.path.join(ROOT, "include")), rel(os.path.join(ROOT, "src")),
                  rel(os.path.join(ROOT, "generated")), numpy.get_include()],
    define_macros=[("_POSIX_C_SOURCE", "200809L"), ("NDEBUG", None)],
    # -fno-wrapv undoes the -fwrapv of Debian's python3 CFLAGS (sysconfig), which the
    # CMake build does not use: with it, the PCA normals' bootstrap on an AVX-512 machine
    # (the x86-64-v4 clones) gave other values than the command line's (normal_var 0.0177
    # instead of 0.0055 on a noisy 20k cube, -B 10; equal with -fno-wrapv, and equal under
    # valgrind, whose CPU has no AVX-512; the object that differs is src/algo/nested.c's):
    # not the same bits, as the package promises. The cause (GCC 12 with -fwrapv selected
    # the centroid in one vector lane of four: nested.c, cov4) is fixed and tested
    # (test_nested_wrapv); -fno-wrapv stays so that the package keeps the CMake flags.
    extra_compile_args=["-std=c11", "-O3", "-fno-wrapv", "-fopenmp", "-fno-math-errno",
                        "-fvisibility=hidden"],
    extra_link_args=["-fopenmp"],
    libraries=["png", "m"],
)

setup(
    name="bootsurf",
    version=version(),
    description="Bootstrap statistics for 3D point clouds: test error, normals with confidence, "
                "denoising, features (numpy front end of libbootsurf)",
    packages=["bootsurf"],
    package_dir={"": "python"},
    package_data={"bootsurf": ["__init__.pyi", "py.typed"]},
    ext_modules=[core],
    install_requires=["numpy"],  # Debian: python3-numpy
    python_requires=">=3.9",
    zip_safe=False,
)
