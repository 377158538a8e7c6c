"""How much does a success map change under a tiny physical perturbation?

    .venv/bin/python benchmarks/map_noise.py
        [--objects table1-row4 …] [--stds 1e-4 1e-3 1e-2] [--seeds 2]
        [--step-ms X (the catch's)] [--scenario F] [--scenario-name NAME] [--workers 2]
        [--out out/map_noise]

The companion of map_convergence.py. That benchmark changes the plant's time step
and asks whether the maps converge; this one keeps the step and perturbs the
throw physically: each arm joint's velocity at the release is offset by a
seeded draw of standard deviation `std` (scenario throw.noise; the watch and
every cell of the map see the same perturbed throw, number 1). For each
object, noise level and seed: the whole 150-cell map, how many cells differ
from the unperturbed map, and against how many two unrelated maps with the
same catch rates would differ by chance, 150 − (p·q + (1 − p)(1 − q))·150.

A map that few cells of which change under perturbations far smaller than a
real robot's is a deterministic, locally robust function of the throw; if a
change of the time step moves many more cells than that, the difference is
the discretization's error, not chaos.

Writes <out>/<std>_seed<k>/<object>_<step>ms.jsonl (one line per cell, as
it finishes; a rerun resumes), the scenario files used there, <out>.json
(the figures) and <out>.png (cells changed against the noise level).
"""

# regrasp_drake before NumPy: it pins NumPy's and OpenBLAS's kernels
# (regrasp_drake/numerics.py), so that results match across x86-64 machines.
import regrasp_drake  # noqa: F401, I001 (first, see above)
import argparse
import sys
from pathlib import Path

import map_convergence as study  # beside this script
import numpy as np


from regrasp_drake import atomic_io, progress, scenario_args

_OBJECTS = ["table1-row4", "table1-row2"]
_STDS = [1e-4, 1e-3, 1e-2]


def _level_dir(out: Path, std: float, seed: int) -> Path:
    return out / (f"std{std:g}_seed{seed}" if std > 0 else "plain")


def noisy(base, std: float, seed: int):
    """The Scenario `base` with only the release's joint-velocity noise
    set."""
    import dataclasses as dc

    from regrasp_drake.station.scenario import ThrowNoise
    return dc.replace(base, throw=dc.replace(base.throw, noise=ThrowNoise(
        joint_velocity_std_rad_per_s=float(std), seed=int(seed))))


def _write_scenario(directory: Path, scenario, label: str | None = None) -> Path:
    """Records `scenario` (the scenario `label` names with release noise)
    whole beside the maps it made."""
    from regrasp_drake.station.scenario import scenario_yaml
    path = directory / "scenario.yaml"
    atomic_io.write_text(path, "# benchmarks/map_noise.py: "
                         f"{label or 'the shipped scenario'} with release "
                         "noise.\n" + scenario_yaml(scenario))
    return path


def changed(plain, other) -> dict:
    """Cells whose outcome differs between boolean maps, and how many two
    independent maps with these catch rates would differ in by chance."""
    a = study.agreement(plain, other)
    return {"changed": a["cells"] - a["same"],
            "chance": round(a["cells"] - a["chance"], 1)}


def summarize(maps: dict, stds) -> dict:
    """maps[name][(std, seed)] as map_at_step rows, (0, 0) the unperturbed
    one. Per object and level: cells changed from the unperturbed map per
    seed (with chance), and the release spin's distance from it."""
    out = {}
    for name, by_level in maps.items():
        plain = by_level[(0.0, 0)]
        levels = {}
        for std in stds:
            rows = [(seed, row) for (s, seed), row in sorted(by_level.items())
                    if s == std]
            levels[f"{std:g}"] = [
                {"seed": seed, "cells_caught": row["cells_caught"],
                 "w_O_shift_rad_per_s": round(float(np.linalg.norm(np.subtract(
                     row["release"]["w_O"], plain["release"]["w_O"]))), 4)}
                | changed(plain["caught"], row["caught"])
                for seed, row in rows]
        out[name] = {"plain_cells_caught": plain["cells_caught"],
                     "by_std": levels}
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--objects", nargs="+", default=_OBJECTS)
    parser.add_argument("--stds", type=float, nargs="+", default=_STDS,
                        help="joint-velocity noise levels, rad/s")
    parser.add_argument("--seeds", type=int, default=2)
    parser.add_argument("--step-ms", type=float, default=None,
                        help="the catch's plant time step, "
                             "catch_time_step_s (default: the scenario's)")
    # The scenario the noise is added to.
    scenario_args.add(parser, target=False)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--out", type=Path, default=Path("out/map_noise"),
                        help="a directory of rows; <out>.json and <out>.png "
                             "beside it")
    return _run(parser.parse_args(argv))


def _run(args) -> int:
    import dataclasses as dc

    from regrasp_drake.errors import InputError
    from regrasp_drake.station.scenario import ThrowNoise, validate
    from regrasp_drake.world.objects import resolve_object
    try:
        given, label = scenario_args.load(args)
        if args.step_ms is None:  # the scenario's catch step
            scenario = given
            args.step_ms = round((scenario.catch_time_step_s
                                  or scenario.plant_config.time_step) * 1e3, 9)
        try:
            base = study._scenario(args.step_ms, given)
        except InputError as e:
            raise InputError(f"--step-ms {args.step_ms:g}: {e}") from None
        for std in args.stds:
            if not std > 0:
                raise InputError(f"--stds {std:g}: expected > 0 rad/s (the "
                                 "unperturbed map is always run)")
            try:
                validate(dc.replace(base, throw=dc.replace(
                    base.throw, noise=ThrowNoise(
                        joint_velocity_std_rad_per_s=std))))
            except InputError as e:
                raise InputError(f"--stds {std:g}: {e}") from None
        if args.seeds < 1:
            raise InputError(f"--seeds {args.seeds}: expected >= 1")
        if args.workers < 1:
            raise InputError(f"--workers {args.workers}: expected >= 1")
        for name in args.objects:
            resolve_object(name=name)
    except InputError as e:
        print(f"map_noise: error: {e}", file=sys.stderr)
        return 2
    import torch
    torch.set_num_threads(1)
    levels = [(0.0, 0)] + [(std, seed) for std in args.stds
                           for seed in range(1, args.seeds + 1)]
    maps = {name: {} for name in args.objects}
    with progress.bar(len(levels) * len(args.objects), "noise levels",
                      "maps") as shown:
        for std, seed in levels:
            directory = _level_dir(args.out, std, seed)
            directory.mkdir(parents=True, exist_ok=True)
            scenario = given if std == 0 else noisy(given, std, seed)
            if std:
                _write_scenario(directory, scenario, label)
            for name in args.objects:
                progress.say(f"{name}, noise {std:g} rad/s, seed {seed}",
                             sys.stderr)
                maps[name][(std, seed)] = study.map_at_step(
                    name, args.step_ms, directory, args.workers,
                    base=scenario)
                shown.update()
    summary = {"step_ms": args.step_ms, "stds_rad_per_s": args.stds,
               "seeds": args.seeds, "scenario": label,
               "objects": summarize(maps, args.stds)}
    atomic_io.write_json(args.out.with_suffix(".json"), summary, indent=None)
    _print(summary)
    _plot(summary, args.out.with_suffix(".png"))
    return 0


def _print(summary):
    for name, s in summary["objects"].items():
        print(f"\n{name}: {s['plain_cells_caught']}/150 catch unperturbed")
        for std, rows in s["by_std"].items():
            cells = ", ".join(f"{r['changed']} (chance {r['chance']:.0f}; "
                              f"spin {r['w_O_shift_rad_per_s']:.4f})"
                              for r in rows)
            print(f"  std {std} rad/s: cells changed by seed {cells}")


def _plot(summary, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6, 4))
    for name, s in summary["objects"].items():
        stds = [float(k) for k in s["by_std"]]
        mean = [np.mean([r["changed"] for r in rows])
                for rows in s["by_std"].values()]
        line, = ax.plot(stds, mean, "o-", label=f"{name}: cells changed")
        for std, rows in zip(stds, s["by_std"].values()):
            ax.scatter([std] * len(rows), [r["changed"] for r in rows],
                       color=line.get_color(), s=10, alpha=0.5)
        chance = [np.mean([r["chance"] for r in rows])
                  for rows in s["by_std"].values()]
        ax.plot(stds, chance, "--", color=line.get_color(), alpha=0.5,
                label=f"{name}: unrelated maps (chance)")
    ax.set_xscale("log")
    ax.set_ylim(0, 150)
    ax.set_xlabel("release joint-velocity noise std (rad/s)")
    ax.set_ylabel("cells changed from the unperturbed map")
    ax.set_title(f"Success maps under seeded throw perturbations, "
                 f"step {summary['step_ms']:g} ms", fontsize=9)
    ax.legend(fontsize=7)
    fig.tight_layout()
    atomic_io.save_figure(fig, path, dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    sys.exit(main())
