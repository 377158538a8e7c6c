"""Palm offsets at one catch cell, fast: the throw is simulated once per
(object, scenario), then each offset's catch from a copy of the state at
the throw's end (the grasp pose set there, as run_episode's at_release
does), so every offset's episode is the one catch_tolerance.py runs.

    PYTHONPATH=. .venv/bin/python studies/catch_tolerance/screen_offsets.py \
        table1-row2 0.20 -0.13 [--scenario F] [--text YAML] \
        [--offsets "dx,dy;dx,dy" | all] [--tag NAME]

Prints one JSON line per offset (the monitor's outcome, the drop reason and
the contact verdict) and a summary line. The watched plan is cached in
out/catch_screen/.
"""
# regrasp_drake before NumPy (regrasp_drake/numerics.py).
import regrasp_drake  # noqa: F401, I001
import argparse
import json
import os
import pickle
import time
from pydrake.math import RigidTransform
from pydrake.systems.analysis import InitializeParams
from regrasp_drake.planning.ik import ArmIk
from regrasp_drake.station.scenario import load_scenario
from regrasp_drake.throw_catch import plan_catch, watch
from regrasp_drake.world.objects import resolve_object
from regrasp_drake.station.station import build_episode_diagram, initialize
from regrasp_drake.station.episode import (read_outcome, read_ending,
                                           release_time, advance_to_outcome)

ap = argparse.ArgumentParser()
ap.add_argument('object')
ap.add_argument('hc', type=float)
ap.add_argument('hd', type=float)
ap.add_argument('--scenario', default='studies/palm_toss/palm_toss_q.yaml')
ap.add_argument('--text', default=None)
ap.add_argument('--offsets', default='all')  # "dx,dy;dx,dy" or all or fails
ap.add_argument('--tag', default='')
a = ap.parse_args()
scenario = load_scenario(a.scenario, text=a.text)
obj = resolve_object(name=a.object)
ik = ArmIk()
base = load_scenario(a.scenario)
os.makedirs('out/catch_screen', exist_ok=True)
cache = (f'out/catch_screen/plan_{a.object}_{os.path.basename(a.scenario)}'
         f'_{base.plant_config.time_step}.pkl')
if os.path.exists(cache):
    X_WG = RigidTransform(pickle.load(open(cache, 'rb')))
else:
    X_WG = plan_catch(base, obj, ik, watch(base, obj, ik)).X_WG
    pickle.dump(X_WG.GetAsMatrix4(), open(cache, 'wb'))
R = range(-20, 21, 10)
if a.offsets == 'all':
    offs = [(dx, dy) for dx in R for dy in R]
else:
    offs = [tuple(int(v) for v in s.split(',')) for s in a.offsets.split(';')]
t0 = time.time()
st = build_episode_diagram(scenario, obj, ik=ik, X_WG=X_WG,
                           catch_parameters=(a.hc, a.hd))
sim = initialize(st, scenario)
tr = release_time(scenario)
sim.AdvanceTo(tr)
saved = sim.get_context().Clone()
grasp = st.controller.grasp_pose
n = 0
out = []
for dx, dy in offs:
    ctx = saved.Clone()
    grasp.set_pose(grasp.GetMyMutableContextFromRoot(ctx),
                   X_WG @ RigidTransform([dx / 1e3, dy / 1e3, 0]))
    sim.reset_context(ctx)
    sim.Initialize(InitializeParams(suppress_initialization_events=True))
    msg = advance_to_outcome(sim, st, scenario)
    c = sim.get_context()
    outcome, gt = read_outcome(st, c, msg)
    end = read_ending(st, c, outcome)
    n += outcome == 'caught'
    row = dict(object=a.object, tag=a.tag, dx_mm=dx, dy_mm=dy, outcome=outcome,
               held=end['held_by_contact'], reason=end['drop_reason'],
               touching=end['touching'], msg=msg)
    out.append(row)
    print(json.dumps(row), flush=True)
held = sum(bool(r["held"]) for r in out)
print(f'SUMMARY {a.tag} {a.object} ({a.hc},{a.hd}) caught {n}/{len(offs)} '
      f'held_by_contact {held} wall {time.time() - t0:.0f}s', flush=True)
