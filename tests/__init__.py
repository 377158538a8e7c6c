# The package first, before any test module imports NumPy: it pins NumPy's
# and OpenBLAS's kernels (regrasp_drake/numerics.py).
import regrasp_drake  # noqa: F401
