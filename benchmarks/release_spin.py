"""How the object leaves the throw, against the moment the fingers open.

    .venv/bin/python benchmarks/release_spin.py [--objects NAME …]
        [--release-times-s 0.26 0.31 0.36 0.41] [--workers 2]
        [--out benchmarks/release_spin]

For each object and each release time (scenario `throw.release_time_s`,
counted from the end of the settling like the throw's knots; the shipped
scenario opens the fingers at 0.31 s): one watching throw, and the object's
state when the throw ends (flight_predictor.free_time_s), the state the
flight predictor learns to predict. Reported: the angular velocity in the
object frame, w_O, whose y component is the spin about the object's axis
from rolling across the opened palm, and the centre of mass's velocity.

The question it answers: is the spin a smooth function of the object, which
a predictor fed with the object's features could learn, or does the roll
switch on and off between neighbouring densities of one geometry? Per
release time it gives the spread of the spin within each geometry (the
densities of one shape) and over all objects.

Writes <out>.json (every object's state at every release time, and the
summary) and <out>.png (spin about the axis against release time, one line
per object, coloured by geometry). About 0.3 s of CPU per throw.
"""

# regrasp_drake before NumPy: it pins NumPy's and OpenBLAS's kernels
# (regrasp_drake/numerics.py), so that results match across x86-64 machines.
import regrasp_drake  # noqa: F401, I001 (first, see above)
import argparse
import dataclasses as dc
import json
import sys
from pathlib import Path

import numpy as np

_RELEASE_TIMES_S = [0.26, 0.31, 0.36, 0.41]


def _throw(args):
    """One watching throw (in a worker): the object's state at the end of
    the throw, as w_O (object frame), v_WCm and p_WCm."""
    name, release_time_s = args
    import torch
    from pydrake.common.eigen_geometry import Quaternion
    from pydrake.math import RotationMatrix

    from regrasp_drake.learning.flight_predictor import free_time_s
    from regrasp_drake.planning.ik import ArmIk
    from regrasp_drake.throw_catch import watch
    from regrasp_drake.world.objects import resolve_object
    torch.set_num_threads(1)
    scenario = _scenario(release_time_s)
    obj = resolve_object(name=name)
    watched = watch(scenario, obj, ArmIk())
    k = int(np.argmin(np.abs(watched.logs.t - free_time_s(scenario))))
    state = watched.logs.object_state[:, k]
    R = RotationMatrix(Quaternion(state[:4] / np.linalg.norm(state[:4])))
    p_OCm_W = R.matrix() @ obj.p_OCm
    w_W = state[7:10]
    return {"object": name, "geometry": obj.geometry,
            "release_time_s": release_time_s,
            "t_s": float(watched.logs.t[k]),
            "w_O": (R.matrix().T @ w_W).tolist(),
            "v_WCm": (state[10:13] + np.cross(w_W, p_OCm_W)).tolist(),
            "p_WCm": (state[4:7] + p_OCm_W).tolist(),
            "state": state.tolist()}


def _scenario(release_time_s: float):
    """The shipped scenario with the fingers opening at release_time_s."""
    from regrasp_drake.station.scenario import load_scenario, validate
    base = load_scenario()
    return validate(dc.replace(base, throw=dc.replace(
        base.throw, release_time_s=release_time_s)))


def summarize(rows, release_times_s) -> dict:
    """Per release time: the spin about the axis (w_O y, rad/s) over all
    objects (min, max), its standard deviation within each geometry, and
    their mean over the geometries."""
    out = {}
    for t in release_times_s:
        at = [r for r in rows if r["release_time_s"] == t]
        spin = {r["object"]: r["w_O"][1] for r in at}
        by_geometry = {}
        for r in at:
            by_geometry.setdefault(r["geometry"], []).append(r["w_O"][1])
        within = {g: round(float(np.std(v)), 3)
                  for g, v in sorted(by_geometry.items())}
        out[f"{t:g}"] = {
            "objects": len(at),
            "spin_min_rad_per_s": round(min(spin.values()), 3),
            "spin_max_rad_per_s": round(max(spin.values()), 3),
            "spin_std_within_geometry_rad_per_s": within,
            "mean_within_geometry_std_rad_per_s": round(
                float(np.mean(list(within.values()))), 3),
            "spin_std_all_rad_per_s": round(
                float(np.std(list(spin.values()))), 3),
        }
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--objects", nargs="+",
                        help="catalogue objects (default: every training "
                             "object and the five Table 1 objects)")
    parser.add_argument("--release-times-s", type=float, nargs="+",
                        default=_RELEASE_TIMES_S)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--out", type=Path,
                        default=Path("benchmarks/release_spin"))
    args = parser.parse_args(argv)

    from regrasp_drake.errors import InputError
    from regrasp_drake.world.objects import load_catalogue, resolve_object
    try:
        for t in args.release_times_s:
            try:
                _scenario(t)
            except InputError as e:
                raise InputError(f"--release-times-s {t:g}: {e}") from None
        if args.workers < 1:
            raise InputError(f"--workers {args.workers}: expected >= 1")
        names = args.objects or [o.name for o in load_catalogue().values()
                                 if o.set in ("train", "test")]
        for name in names:
            resolve_object(name=name)
    except InputError as e:
        print(f"release_spin: error: {e}", file=sys.stderr)
        return 2

    tasks = [(name, t) for t in args.release_times_s for name in names]
    rows = []
    if args.workers == 1:
        results = map(_throw, tasks)
    else:
        import multiprocessing
        pool = multiprocessing.get_context("fork").Pool(args.workers)
        results = pool.imap(_throw, tasks)  # in the order of `tasks`
    for k, row in enumerate(results, 1):
        rows.append(row)
        print(f"\r{k}/{len(tasks)} throws", end="", file=sys.stderr,
              flush=True)
    print(file=sys.stderr)
    if args.workers != 1:
        pool.close()
        pool.join()
    summary = summarize(rows, args.release_times_s)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.with_suffix(".json").write_text(json.dumps(
        {"release_times_s": args.release_times_s, "summary": summary,
         "throws": rows}) + "\n")
    _print(summary)
    _plot(rows, args.release_times_s, args.out.with_suffix(".png"))
    return 0


def _print(summary):
    print("release s | objects | spin about the axis, min … max rad/s | "
          "std within a geometry (mean) | std over all")
    for t, s in summary.items():
        print(f"{t:>9} | {s['objects']:7d} | {s['spin_min_rad_per_s']:7.2f} … "
              f"{s['spin_max_rad_per_s']:6.2f} | "
              f"{s['mean_within_geometry_std_rad_per_s']:6.2f} | "
              f"{s['spin_std_all_rad_per_s']:6.2f}")


def _plot(rows, release_times_s, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    geometries = sorted({r["geometry"] for r in rows})
    colours = plt.get_cmap("tab20")(np.linspace(0, 1, max(len(geometries), 2)))
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for name in dict.fromkeys(r["object"] for r in rows):
        mine = sorted((r["release_time_s"], r["w_O"][1], r["geometry"])
                      for r in rows if r["object"] == name)
        g = geometries.index(mine[0][2])
        ax.plot([m[0] for m in mine], [m[1] for m in mine], "o-", ms=3,
                lw=0.8, alpha=0.7, color=colours[g])
    for g, geometry in enumerate(geometries):
        ax.plot([], [], color=colours[g], label=geometry)
    ax.set_xticks(release_times_s)
    ax.set_xlabel("moment the fingers open (s after the settling)")
    ax.set_ylabel("spin about the object's axis at the throw's end (rad/s)")
    ax.set_title("Release spin: one line per object, coloured by geometry",
                 fontsize=9)
    ax.legend(fontsize=6, ncol=2)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    sys.exit(main())
