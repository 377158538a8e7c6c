"""regrasp-drake: regrasp planning through throwing and catching, in Drake."""

from regrasp_drake import numerics

# Before NumPy is imported: the same kernels, and results, on every x86-64
# machine with AVX2 (see numerics.py).
numerics.pin()

__version__ = "0.1.0"
