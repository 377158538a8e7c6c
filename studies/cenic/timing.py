"""Wall time of a watched palm toss, discrete 0.25 ms against CENIC 1e-5 and
1e-4, interleaved (the machine's load moves single timings 2-3x): three
objects, twice, the second time in reverse order of the settings.

    .venv/bin/python studies/cenic/timing.py
"""

# regrasp_drake before NumPy (regrasp_drake/numerics.py).
import regrasp_drake  # noqa: F401, I001
import json

from regrasp_drake.planning.ik import ArmIk
from regrasp_drake.station.scenario import load_scenario
from regrasp_drake.throw_catch import watch
from regrasp_drake.world.objects import load_catalogue

CENIC = ("{plant_config: {time_step: 0}, catch_time_step_s: null, "
         "simulator_config: "
         "{integration_scheme: cenic, accuracy: %s}}")
SETTINGS = {"discrete 0.25 ms": "{plant_config: {time_step: 0.00025}}",
            "CENIC 1e-5": CENIC % "1e-5",
            "CENIC 1e-4": CENIC % "1e-4"}
OBJECTS = ["can-d100-1", "table1-row1", "hammer-d400-6"]


def main() -> None:
    ik, catalogue = ArmIk(), load_catalogue()
    scenarios = {k: load_scenario(text=v)
                 for k, v in SETTINGS.items()}
    walls = {k: [] for k in SETTINGS}
    for rep in range(2):
        for name in OBJECTS:
            order = list(SETTINGS) if rep == 0 else list(SETTINGS)[::-1]
            for label in order:
                w = watch(scenarios[label], catalogue[name], ik)
                walls[label].append(round(w.wall_s, 2))
                print(rep, name, label, round(w.wall_s, 2), flush=True)
    print(json.dumps({k: {"wall_s": v, "mean": round(sum(v) / len(v), 2)}
                      for k, v in walls.items()}))


if __name__ == "__main__":
    main()
