"""regrasp-drake: regrasp planning through throwing and catching, in Drake.

The public API (regrasp_drake/api.py; docs/api.md):

    import regrasp_drake as rd
    run = rd.regrasp(rd.load_object("table1-row2"), rd.Target("flip"),
                     watch=False, max_throws=1)
    print(run.regrasp_line())
    run.save_replay("replay.html")
"""

from regrasp_drake import numerics

# Before NumPy is imported: the same kernels, and results, on every x86-64
# machine with AVX2 (see numerics.py).
numerics.pin()

__version__ = "0.1.0"

__all__ = ["Episode", "Run", "Target", "apply", "catch", "learn",
           "load_object", "load_scenario", "regrasp"]


def __getattr__(name: str):
    """The API's names, imported on first use: `import regrasp_drake` stays
    cheap (the command line and worker processes import it first, before
    NumPy, Drake and torch)."""
    if name in __all__:
        from regrasp_drake import api
        return getattr(api, name)
    raise AttributeError(f"module 'regrasp_drake' has no attribute {name!r}")


def __dir__():
    return sorted(list(globals()) + __all__)
