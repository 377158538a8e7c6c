"""What one plant step of a catch episode costs, and what does not change it.

    .venv/bin/python studies/episode_cost/step_cost.py [--object table1-row2]
        [--repeats 3] [--json out/episode_cost.json]

Records one catch episode's plant inputs (benchmarks/episode_benchmark.py's
record_plant_inputs: the throw at its step to the release, the catch at
catch_time_step_s from there) and replays its physics alone (the same plant,
the recorded inputs, no controller and no Python system), timing the wall
time per plant step in windows of the episode: the throw (the object on the
palm), the flight (nothing touches the object) and the catch (fingers and
palm on it). The flight window is replayed again with variants that change
the physics, to see what the per-step cost is made of: every collision pair
filtered out (no contact query finds anything), and Drake's other discrete
contact approximations ("sap", "lagged"). Prints a table and writes JSON.
"""

# regrasp_drake before NumPy: it pins NumPy's and OpenBLAS's kernels.
import regrasp_drake  # noqa: F401, I001
import argparse
import copy
import json
import statistics
import sys
from pathlib import Path


sys.path.insert(0, str(Path(__file__).parents[2] / "benchmarks"))
from episode_benchmark import (  # noqa: E402
    record_plant_inputs,
    replayed_physics_wall_s,
)


def replay(obj, segment, a, e, *, approximation=None, no_collisions=False):
    """Wall seconds per plant step replaying `segment`'s steps a..e (the
    benchmark's replay of the physics alone), the plant changed as asked."""
    from pydrake.geometry import CollisionFilterDeclaration, GeometrySet, Role
    scenario = copy.deepcopy(segment.scenario)
    if approximation:
        scenario.plant_config.discrete_contact_approximation = approximation

    def no_contact(plant, scene_graph):
        ids = scene_graph.model_inspector().GetAllGeometryIds(Role.kProximity)
        scene_graph.collision_filter_manager().Apply(
            CollisionFilterDeclaration().ExcludeWithin(GeometrySet(ids)))
    wall, _ = replayed_physics_wall_s(
        obj, segment, segment.k0 + a, k_end=segment.k0 + e,
        scenario=scenario, configure=no_contact if no_collisions else None)
    return wall / (e - a)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--object", default="table1-row2")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--json", type=Path,
                        default=Path("out/episode_cost.json"))
    args = parser.parse_args(argv)
    import torch

    from regrasp_drake.planning.ik import ArmIk
    from regrasp_drake.station.scenario import load_scenario
    from regrasp_drake.throw_catch import plan_catch, watch
    from regrasp_drake.world.objects import resolve_object
    torch.set_num_threads(1)
    scenario = load_scenario()
    obj = resolve_object(name=args.object)
    ik = ArmIk(scenario.directives)
    plan = plan_catch(scenario, obj, ik, watch(scenario, obj, ik))
    segments, _ = record_plant_inputs(
        scenario, obj, ik, plan.X_WG,
        (scenario.catch.h_catch_m, scenario.catch.h_down_m))
    throw_seg, catch_seg = segments
    n = len(catch_seg.u_arm)
    # The flight: the catch segment's first 40 % (the object meets the
    # hand at about half of it for this object; checked below by the
    # contact-free replay costing the same).
    windows = {
        "throw (object on the palm), 0.25 ms": (throw_seg, 0,
                                                len(throw_seg.u_arm), {}),
        "flight (no contact), 1 ms": (catch_seg, 0, int(0.4 * n), {}),
        "catch (in contact), 1 ms": (catch_seg, int(0.55 * n), n, {}),
        "flight, every collision filtered out": (
            catch_seg, 0, int(0.4 * n), {"no_collisions": True}),
        "flight, approximation sap": (catch_seg, 0, int(0.4 * n),
                                      {"approximation": "sap"}),
        "flight, approximation lagged": (catch_seg, 0, int(0.4 * n),
                                         {"approximation": "lagged"}),
        "catch, approximation sap": (catch_seg, int(0.55 * n), n,
                                     {"approximation": "sap"}),
        "catch, approximation lagged": (catch_seg, int(0.55 * n), n,
                                        {"approximation": "lagged"}),
    }
    report = {"object": obj.name, "repeats": args.repeats, "windows": {}}
    for name, (segment, a, e, options) in windows.items():
        us = statistics.median(1e6 * replay(obj, segment, a, e, **options)
                               for _ in range(args.repeats))
        t = (segment.k0 + a) * segment.dt, (segment.k0 + e) * segment.dt
        report["windows"][name] = {
            "t_s": [round(t[0], 4), round(t[1], 4)], "steps": e - a,
            "us_per_step": round(us, 1),
            "physics_real_time_factor": round(1e6 * segment.dt / us, 2)}
        print(f"{name:40s} t {t[0]:.3f}-{t[1]:.3f} s  {us:7.1f} us/step  "
              f"physics alone {1e6 * segment.dt / us:5.2f}x real time")
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps(report, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
