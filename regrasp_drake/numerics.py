"""The same floating-point results on every x86-64 machine with AVX2.

NumPy picks its SIMD kernels (sin, cos, exp, reductions, …) at import time
from the CPU's features, and its OpenBLAS picks its matrix kernels the same
way. On a machine with AVX-512 both take other kernels than on an AVX2-only
one, whose results differ in the last bits. A throw that rolls the object
across the palm amplifies such bits: measured with the release-spin
study (the finger throw's; git history keeps it), the object's state at
the end of the throw differed by up to 0.5 (rad/s in the spin) for 7 of
the 56 training objects between the machine that generated the first 96
maps of models/dataset (AVX2) and an AVX-512 one, and by 0 for the rest;
with the kernels pinned as below the AVX-512 machine reproduced that
machine's states bit for bit.

So before NumPy is imported, `pin()` (called when `regrasp_drake` is
imported) asks for the AVX2 kernels on every x86-64 machine that has AVX2:
- NPY_DISABLE_CPU_FEATURES: NumPy's AVX-512 dispatch targets. NumPy ignores
  the ones a machine lacks (numpy/_core/src/common/npy_cpu_features.c: only
  enabling an unsupported feature is an error).
- OPENBLAS_CORETYPE=Haswell: OpenBLAS's AVX2 kernels (only when the CPU has
  AVX2 and FMA: on an older CPU they would not run).
A variable the user has set is left as it is. Drake's own computations
needed nothing more: with these two pinned, the AVX-512 machine reproduced
the AVX2 machine's states.

Import `regrasp_drake` before NumPy (the package's commands, scripts and
tests do); imported after it, `pin()` cannot take effect and says so with a
RuntimeWarning (NumPy and OpenBLAS read the variables once, when NumPy is
imported). `status()` tells whether the pin took effect in this process.
"""

import os
import sys
import warnings

NUMPY_DISABLED = "X86_V4 AVX512_ICL AVX512_SPR"
OPENBLAS_CORETYPE = "Haswell"
# The variables pin() sets, to pass on to processes that do not inherit
# this one's environment (a Ray cluster's workers).
VARIABLES = ("NPY_DISABLE_CPU_FEATURES", "OPENBLAS_CORETYPE")


def _cpu_flags() -> set[str]:
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("flags"):
                    return set(line.split(":", 1)[1].split())
    except OSError:
        pass
    return set()


def pin() -> None:
    """Sets the variables above for this process and its children, unless
    the machine is not x86-64 with AVX2 and FMA, or NumPy is already
    imported: too late, then, and a RuntimeWarning says so, unless the
    variables were set before (by the user, or inherited from a pinned
    process)."""
    flags = _cpu_flags()
    if not {"avx2", "fma"} <= flags:
        return
    if "numpy" in sys.modules:
        if not _set_before():
            warnings.warn(
                "regrasp_drake was imported after NumPy: NumPy's and "
                "OpenBLAS's kernels are not pinned (regrasp_drake/"
                "numerics.py), so results may differ in their last bits "
                "from other machines'; import regrasp_drake before numpy, "
                "or set NPY_DISABLE_CPU_FEATURES='X86_V4 AVX512_ICL "
                "AVX512_SPR' and OPENBLAS_CORETYPE=Haswell",
                RuntimeWarning, stacklevel=_importer_stacklevel())
        return
    if "NPY_ENABLE_CPU_FEATURES" not in os.environ:
        os.environ.setdefault("NPY_DISABLE_CPU_FEATURES", NUMPY_DISABLED)
    os.environ.setdefault("OPENBLAS_CORETYPE", OPENBLAS_CORETYPE)


def _set_before() -> bool:
    """Whether NumPy's and OpenBLAS's variables are set (to anything: a
    user's choice is kept as it is)."""
    numpy_set = ("NPY_DISABLE_CPU_FEATURES" in os.environ
                 or "NPY_ENABLE_CPU_FEATURES" in os.environ)
    return numpy_set and "OPENBLAS_CORETYPE" in os.environ


def _importer_stacklevel() -> int:
    """The stack level of the frame that imported regrasp_drake, for the
    warning to name the user's line: past the package's frames and the
    import machinery's (which `warnings` skips without counting them)."""
    frame, level = sys._getframe(1), 1
    while frame is not None:
        name = frame.f_code.co_filename
        if "importlib" in name and "_bootstrap" in name:
            frame = frame.f_back  # not counted by warnings
            continue
        if not frame.f_globals.get("__name__", "").startswith("regrasp_drake"):
            break
        frame, level = frame.f_back, level + 1
    return level


def status() -> dict:
    """What this process runs with: whether NumPy dispatches to AVX-512
    kernels, the OpenBLAS core type asked for, and whether the CPU has
    AVX-512. For provenance."""
    try:  # NumPy 2; NumPy 1 calls the module numpy.core.
        from numpy._core._multiarray_umath import __cpu_features__ as features
    except ImportError:
        from numpy.core._multiarray_umath import __cpu_features__ as features
    return {"numpy_avx512_kernels": any(
                features.get(k, False) for k in NUMPY_DISABLED.split()),
            "openblas_coretype": os.environ.get("OPENBLAS_CORETYPE"),
            "avx512_cpu": "avx512f" in _cpu_flags()}
