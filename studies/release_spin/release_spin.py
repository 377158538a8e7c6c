"""How the object leaves the throw, against how the hand lets it go.

    .venv/bin/python studies/release_spin/release_spin.py [--objects NAME …]
        [--release-times-s 0.26 0.31 0.36 0.41] [--hold-closures 0.5]
        [--cross-validate] [--workers 2] [--out studies/release_spin/release_spin]

For each object and each throw configuration, a release time (scenario
`throw.release_time_s`, counted from the end of the settling like the
throw's knots; shipped: 0.31 s) and a hold closure (`throw.hold_closure`,
how far the fingers close on the object for the throw; shipped: 0.5): one
watching throw, and the object's state when the throw ends
(flight_predictor.free_time_s), the state the flight predictor learns to
predict. Reported: the angular velocity in the object frame, w_O, whose y
component is the spin about the object's axis from rolling across the
opened palm, and the centre of mass's velocity.

The question it answers: is the spin a smooth function of the object, which
a predictor fed with the object's features could learn, or does the roll
switch on and off between neighbouring densities of one geometry? Per
configuration it gives the spread of the spin within each geometry (the
densities of one shape) and over all objects. With --cross-validate, also
the flight predictor's leave-one-geometry-out errors on the training
objects' flights of that configuration (flight_predictor.cross_validate:
what first-throw mode would face with that throw).

Writes <out>.jsonl (one line per throw, as it finishes; a rerun resumes),
<out>.json (every object's state in every configuration, and the summary)
and <out>.png (spin about the axis per configuration, one line per
object, coloured by geometry). About 0.3 s of CPU per throw.
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
_HOLD_CLOSURES = [0.5]


def _throw(args):
    """One watching throw (in a worker): the object's state at the end of
    the throw, as w_O (object frame), v_WCm and p_WCm."""
    name, release_time_s, hold_closure = args
    import torch
    from pydrake.common.eigen_geometry import Quaternion
    from pydrake.math import RotationMatrix

    from regrasp_drake.learning.flight_predictor import free_time_s
    from regrasp_drake.planning.ik import ArmIk
    from regrasp_drake.throw_catch import watch
    from regrasp_drake.world.objects import resolve_object
    torch.set_num_threads(1)
    scenario = _scenario(release_time_s, hold_closure)
    obj = resolve_object(name=name)
    watched = watch(scenario, obj, ArmIk())
    k = int(np.argmin(np.abs(watched.logs.t - free_time_s(scenario))))
    state = watched.logs.object_state[:, k]
    R = RotationMatrix(Quaternion(state[:4] / np.linalg.norm(state[:4])))
    p_OCm_W = R.matrix() @ obj.p_OCm
    w_W = state[7:10]
    return {"object": name, "geometry": obj.geometry,
            "release_time_s": release_time_s, "hold_closure": hold_closure,
            "t_s": float(watched.logs.t[k]),
            "w_O": (R.matrix().T @ w_W).tolist(),
            "v_WCm": (state[10:13] + np.cross(w_W, p_OCm_W)).tolist(),
            "p_WCm": (state[4:7] + p_OCm_W).tolist(),
            "state": state.tolist()}


def _scenario(release_time_s: float, hold_closure: float):
    """The shipped scenario with the fingers opening at release_time_s,
    closed to hold_closure for the throw."""
    from regrasp_drake.station.scenario import load_scenario, validate
    base = load_scenario()
    return validate(dc.replace(base, throw=dc.replace(
        base.throw, release_time_s=release_time_s,
        hold_closure=hold_closure)))


def _key(row) -> tuple:
    return row["object"], row["release_time_s"], row["hold_closure"]


def config_key(release_time_s: float, hold_closure: float) -> str:
    return f"release {release_time_s:g} s, hold {hold_closure:g}"


def summarize(rows, configs) -> dict:
    """Per configuration (release time, hold closure): the spin about the
    axis (w_O y, rad/s) over all objects (min, max), its standard deviation
    within each geometry, and their mean over the geometries."""
    out = {}
    for t, h in configs:
        at = [r for r in rows
              if r["release_time_s"] == t and r["hold_closure"] == h]
        spin = {r["object"]: r["w_O"][1] for r in at}
        by_geometry = {}
        for r in at:
            by_geometry.setdefault(r["geometry"], []).append(r["w_O"][1])
        within = {g: round(float(np.std(v)), 3)
                  for g, v in sorted(by_geometry.items())}
        out[config_key(t, h)] = {
            "release_time_s": t, "hold_closure": h,
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


def _cross_validate(rows, t, h) -> dict:
    """The flight predictor's leave-one-geometry-out errors on the training
    objects' flights of configuration (t, h)."""
    from regrasp_drake.learning.flight_predictor import cross_validate, summarize
    from regrasp_drake.planning.ik import ArmIk
    from regrasp_drake.world.objects import resolve_object
    train = [r for r in rows if r["release_time_s"] == t
             and r["hold_closure"] == h]
    objects = [resolve_object(name=r["object"]) for r in train]
    keep = [k for k, o in enumerate(objects) if o.set == "train"]
    return summarize(cross_validate(
        [objects[k] for k in keep],
        [np.asarray(train[k]["state"]) for k in keep], _scenario(t, h),
        ArmIk()))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--objects", nargs="+",
                        help="catalogue objects (default: every training "
                             "object and the five Table 1 objects)")
    parser.add_argument("--release-times-s", type=float, nargs="+",
                        default=_RELEASE_TIMES_S)
    parser.add_argument("--hold-closures", type=float, nargs="+",
                        default=_HOLD_CLOSURES)
    parser.add_argument("--cross-validate", action="store_true",
                        help="also the flight predictor's leave-one-"
                             "geometry-out errors per configuration")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--out", type=Path,
                        default=Path(__file__).with_suffix(""))
    args = parser.parse_args(argv)

    from regrasp_drake.errors import InputError
    from regrasp_drake.world.objects import load_catalogue, resolve_object
    configs = [(t, h) for h in args.hold_closures
               for t in args.release_times_s]
    try:
        from regrasp_drake.station.scenario import load_scenario
        shipped = load_scenario().throw
        for t in args.release_times_s:
            try:
                _scenario(t, shipped.hold_closure)
            except InputError as e:
                raise InputError(f"--release-times-s {t:g}: {e}") from None
        for h in args.hold_closures:
            try:
                _scenario(shipped.release_time_s, h)
            except InputError as e:
                raise InputError(f"--hold-closures {h:g}: {e}") from None
        if args.workers < 1:
            raise InputError(f"--workers {args.workers}: expected >= 1")
        names = args.objects or [o.name for o in load_catalogue().values()
                                 if o.set in ("train", "test")]
        for name in names:
            resolve_object(name=name)
    except InputError as e:
        print(f"release_spin: error: {e}", file=sys.stderr)
        return 2

    from regrasp_drake.grid import append_rows, read_rows
    args.out.parent.mkdir(parents=True, exist_ok=True)
    lines = args.out.with_suffix(".jsonl")
    done = read_rows(lines, _key)  # a rerun resumes
    tasks = [(name, t, h) for t, h in configs for name in names
             if (name, t, h) not in done]
    if tasks:
        append_rows(_throw, tasks, lines, done, _key, workers=args.workers,
                    label="release spin", unit="throws")
    rows = [done[(name, t, h)] for t, h in configs for name in names]
    summary = summarize(rows, configs)
    if args.cross_validate:
        for t, h in configs:
            print(f"cross-validating the flight predictor: "
                  f"{config_key(t, h)}", file=sys.stderr)
            summary[config_key(t, h)]["predictor_cv"] = _cross_validate(
                rows, t, h)
    args.out.with_suffix(".json").write_text(json.dumps(
        {"release_times_s": args.release_times_s,
         "hold_closures": args.hold_closures, "summary": summary,
         "throws": rows}) + "\n")
    _print(summary)
    _plot(rows, configs, args.out.with_suffix(".png"))
    return 0


def _print(summary):
    print("configuration | objects | spin about the axis, min … max rad/s | "
          "std within a geometry (mean) | std over all | predictor "
          "(leave one geometry out): offset at catch mm, axis deg (means)")
    for key, s in summary.items():
        cv = s.get("predictor_cv")
        cv = (f"{cv['offset_at_catch_mm']['mean']:.0f}, "
              f"{cv['axis_at_catch_deg']['mean']:.0f}" if cv else "-")
        print(f"{key} | {s['objects']} | {s['spin_min_rad_per_s']:.2f} … "
              f"{s['spin_max_rad_per_s']:.2f} | "
              f"{s['mean_within_geometry_std_rad_per_s']:.2f} | "
              f"{s['spin_std_all_rad_per_s']:.2f} | {cv}")


def _plot(rows, configs, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    geometries = sorted({r["geometry"] for r in rows})
    colours = plt.get_cmap("tab20")(np.linspace(0, 1, max(len(geometries), 2)))
    fig, ax = plt.subplots(figsize=(max(7, 1.2 * len(configs)), 4.5))
    for name in dict.fromkeys(r["object"] for r in rows):
        spin = {(r["release_time_s"], r["hold_closure"]): r["w_O"][1]
                for r in rows if r["object"] == name}
        geometry = next(r["geometry"] for r in rows if r["object"] == name)
        ax.plot(range(len(configs)), [spin[c] for c in configs], "o-", ms=3,
                lw=0.8, alpha=0.7, color=colours[geometries.index(geometry)])
    for g, geometry in enumerate(geometries):
        ax.plot([], [], color=colours[g], label=geometry)
    ax.set_xticks(range(len(configs)))
    ax.set_xticklabels([f"{t:g} s\nhold {h:g}" for t, h in configs],
                       fontsize=7)
    ax.set_xlabel("moment the fingers open (s after the settling), finger "
                  "closure while held")
    ax.set_ylabel("spin about the object's axis at the throw's end (rad/s)")
    ax.set_title("Release spin: one line per object, coloured by geometry",
                 fontsize=9)
    ax.legend(fontsize=6, ncol=2)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    sys.exit(main())
