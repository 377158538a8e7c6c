"""Throw a Table 1 object, watch its flight, and catch it with the shipped
network's parameters; save the replay.

    .venv/bin/python examples/throw_catch.py [--object table1-row2]
        [--object-file examples/my_object.yaml] [--out out/throw_catch.html]
        [--target flip] [--offset-mm 0]

Throw 1 watches; the offline stage plans the catch; the trained network in
models/ predicts (h_catch, h_down) from (v_catch, h_cm, r_cm, d_obj,
v_conv), quantized to its grid cell; throw 2 catches. Writes
throw_catch.html (the Meshcat replay of throw 2, self-contained) and
throw_catch.png (the sensors over time) in out/ at the top of the
repository (git-ignored; --out elsewhere), and prints the outcome and the
regrasp it made: the target grasp (default flip, +0 mm: end over end, the
palm under the centre of mass; planning/grasp.py) and the grasp achieved.
"""

# regrasp_drake before NumPy: it pins NumPy's and OpenBLAS's kernels
# (regrasp_drake/numerics.py), so that results match across x86-64 machines.
import regrasp_drake  # noqa: F401, I001 (first, see above)
import argparse
import json
import sys
from pathlib import Path

import torch

from regrasp_drake.errors import InputError
from regrasp_drake.learning.learning_phase import network_features, predict
from regrasp_drake.parameter_space import cell_parameters, nearest_cell
from regrasp_drake.paths import MODELS_DIR, OUT_DIR
from regrasp_drake.planning.ik import ArmIk
from regrasp_drake.plots import plot_episode
from regrasp_drake.episode.run import run_episode
from regrasp_drake.station.mlp_system import load_weights
from regrasp_drake.planning.grasp import Target, check_reachable
from regrasp_drake.episode.replay import make_meshcat
from regrasp_drake.station.scenario import load_scenario, target_of, with_target
from regrasp_drake.throw_catch import (
    episode_caption,
    plan_catch,
    save_replay,
    watch,
)
from regrasp_drake.world.objects import resolve_object


def main() -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--object", help="a catalogue object (default "
                        "table1-row2), or with --object-file one of the file's")
    parser.add_argument("--object-file", type=Path,
                        help="your own objects (its first unless --object)")
    parser.add_argument("--out", type=Path, default=OUT_DIR / "throw_catch.html")
    parser.add_argument("--target", default="flip",
                        choices=("keep", "flip", "turn", "any"),
                        help="the grasp to end in (default flip)")
    parser.add_argument("--offset-mm", type=float, default=0.0,
                        help="the palm centre along the object's axis from "
                             "its centre of mass, mm (default 0)")
    args = parser.parse_args()
    torch.set_num_threads(1)
    try:
        scenario = with_target(load_scenario(),
                               Target(args.target, args.offset_mm))
        obj = resolve_object(
            name=args.object or (None if args.object_file else "table1-row2"),
            file=args.object_file)
        check_reachable(target_of(scenario), obj)
        model, _ = load_weights(MODELS_DIR / scenario.catch.weights)
        ik = ArmIk(scenario.directives)
        plan = plan_catch(scenario, obj, ik, watch(scenario, obj, ik))
        raw, _ = predict(model, network_features(obj, plan.catch_point))
        h_catch, h_down = cell_parameters(nearest_cell(*raw))
    except InputError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    meshcat = make_meshcat()
    result = run_episode(scenario, obj, ik=ik, X_WG=plan.X_WG,
                         catch_parameters=(h_catch, h_down), meshcat=meshcat,
                         throw_number=2)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    save_replay(meshcat, args.out, result, plan, ik,
                caption=episode_caption(result))
    plot_episode(result, args.out.with_suffix(".png"))
    print(json.dumps(result.summary() | {
        "network_output": [round(x, 4) for x in raw],
        "plan": plan.as_dict()}, indent=1))
    print(result.regrasp_line())
    print(f"replay: {args.out}  sensors: {args.out.with_suffix('.png')}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
