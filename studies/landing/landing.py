"""Issue 54 item 1: the landing, recorded at every plant step.

For each catch (object, target, cell, palm shifts, catch step) the episode
runs exactly as `regrasp --first-throw --max-throws 1` runs it (the flight
predictor's plan, the network's cell or a given one, the release
correction), with a Simulator monitor (called after every step; it changes
nothing in the simulation) that reads the plant: the object's and the palm's
(`palm_surface`) poses and velocities, the contact results near the landing,
and the grasp (planning/grasp.measure) at every step. One JSON row per
catch goes to --out (JSONL); `--plot` draws the plot from the rows.

  cd /work/wt-study && PYTHONPATH=/work/wt-study \
    /work/main/.venv/bin/python studies/landing/landing.py --set main \
    --out studies/landing/rows.jsonl        # the 32 base catches
  ... --set offsets | cells | fine           # the other groups
  ... --plot studies/landing/landing.png --out studies/landing/rows.jsonl
"""

# regrasp_drake before NumPy: it pins NumPy's and OpenBLAS's kernels
# (regrasp_drake/numerics.py), so that results match across x86-64 machines.
import regrasp_drake  # noqa: F401, I001 (first, see above)
import argparse
import json
import time

import numpy as np
import torch
from pydrake.systems.framework import EventStatus

from regrasp_drake.episode import episode as episode_module
from regrasp_drake.episode.result import start_grasp
from regrasp_drake.learning.flight_predictor import FlightPredictor
from regrasp_drake.learning.learning_phase import _Phase
from regrasp_drake.learning.planner import PAPER_NETWORK
from regrasp_drake.parameter_space import cell_parameters
from regrasp_drake.paths import MODELS_DIR
from regrasp_drake.planning import grasp
from regrasp_drake.planning.catch_plan import lowest_point_along
from regrasp_drake.planning.ik import ArmIk
from regrasp_drake.station.catch_state_machine import Phase
from regrasp_drake.station.mlp_system import load_weights
from regrasp_drake.station.scenario import (
    load_scenario,
    with_catch_time_step,
    with_target,
)
from regrasp_drake.throw_catch import (
    ReleaseCorrection,
    planned_grasp,
    release_correction,
)
from regrasp_drake.world.objects import resolve_object

torch.set_num_threads(1)

ZERO_SHIFTS = "{catch: {palm_toward_landing_end_m: 0.0, palm_toward_fingers_m: 0.0}}"
# Contacts are read while the object's lowest point is within this of the
# palm's plane, [m], and at most this long after the first contact, [s].
CONTACT_GAP_M = 0.03
CONTACT_WINDOW_S = 0.3


class Recorder:
    """The Simulator monitor: one row per step."""

    def __init__(self, obj, start_R_PO):
        self.obj, self.start_R_PO = obj, np.asarray(start_R_PO)
        self.rows = []
        self.t_contact = None
        self.episode = None

    def attach(self, simulator, episode):
        self.episode = episode
        station = episode.station
        self.plant = station.plant
        self.body = station.object_body
        self.palm_frame = self.plant.GetFrameByName("palm_surface",
                                                    station.hand)
        inspector = station.scene_graph.model_inspector() if hasattr(
            station, "scene_graph") else None
        self.inspector = inspector
        simulator.set_monitor(self.monitor)

    def monitor(self, root_context):
        t = root_context.get_time()
        if self.rows and t <= self.rows[-1]["t"] + 1e-12:
            return EventStatus.Succeeded()
        plant, obj = self.plant, self.obj
        pc = plant.GetMyContextFromRoot(root_context)
        X_WP = self.palm_frame.CalcPoseInWorld(pc)
        V_WP = self.palm_frame.CalcSpatialVelocityInWorld(pc)
        X_WO = plant.EvalBodyPoseInWorld(pc, self.body)
        V_WO = plant.EvalBodySpatialVelocityInWorld(pc, self.body)
        R_WP = X_WP.rotation().matrix()
        R_WO = X_WO.rotation().matrix()
        p_WP = X_WP.translation()
        p_WCm = X_WO.translation() + R_WO @ obj.p_OCm
        v_WCm = V_WO.translational() + np.cross(V_WO.rotational(),
                                                R_WO @ obj.p_OCm)
        w_WP, v_WPo = V_WP.rotational(), V_WP.translational()
        v_rel = R_WP.T @ (v_WCm - v_WPo - np.cross(w_WP, p_WCm - p_WP))
        w_rel = R_WP.T @ (V_WO.rotational() - w_WP)
        p_PCm = R_WP.T @ (p_WCm - p_WP)
        X_PO = X_WP.inverse() @ X_WO
        g = grasp.measure(obj, X_PO.rotation().matrix(), X_PO.translation(),
                          self.start_R_PO)
        gap = lowest_point_along(obj, R_WO, X_WO.translation(),
                                 R_WP[:, 2]) - p_WP @ R_WP[:, 2]
        row = {"t": t, "p_PCm": p_PCm, "v_rel": v_rel, "w_rel": w_rel,
               "v_palm_P": R_WP.T @ v_WPo, "w_palm_P": R_WP.T @ w_WP,
               "offset_mm": g.offset_mm, "tilt_deg": g.tilt_deg,
               "axis": g.axis, "gap": gap, "contacts": None}
        in_window = (gap < CONTACT_GAP_M and (
            self.t_contact is None or t < self.t_contact + CONTACT_WINDOW_S))
        if in_window:
            row["contacts"] = self.contacts(pc, X_WO, X_WP)
            if row["contacts"] and self.t_contact is None:
                self.t_contact = t
        self.rows.append(row)
        return EventStatus.Succeeded()

    def contacts(self, pc, X_WO, X_WP):
        """(other body's name, contact point in the object frame, in the
        palm frame) of every contact of the object."""
        plant = self.plant
        results = plant.get_contact_results_output_port().Eval(pc)
        out = []
        X_OW, X_PW = X_WO.inverse(), X_WP.inverse()
        bi = self.body.index()
        for k in range(results.num_point_pair_contacts()):
            info = results.point_pair_contact_info(k)
            a, b = info.bodyA_index(), info.bodyB_index()
            if bi not in (a, b):
                continue
            other = plant.get_body(b if a == bi else a).name()
            p = info.contact_point()
            out.append((other, X_OW @ p, X_PW @ p))
        for k in range(results.num_hydroelastic_contacts()):
            info = results.hydroelastic_contact_info(k)
            surface = info.contact_surface()
            # bodies of the two geometries
            ids = (surface.id_M(), surface.id_N())
            names = [plant.GetBodyFromFrameId(
                self.inspector.GetFrameId(i)).name() for i in ids]
            if self.body.name() not in names:
                continue
            other = names[1] if names[0] == self.body.name() else names[0]
            p = surface.centroid()
            out.append((other, X_OW @ p, X_PW @ p))
        return out


CURRENT = {"recorder": None}
_original_advance = episode_module.advance_to_outcome


def _recording_advance(simulator, episode, scenario, t_final=None):
    rec = CURRENT["recorder"]
    if rec is not None and t_final is None and rec.episode is None:
        rec.attach(simulator, episode)
    return _original_advance(simulator, episode, scenario, t_final)


episode_module.advance_to_outcome = _recording_advance


def scenario_for(kind, offset_mm, shifts, step=None):
    s = load_scenario(text=ZERO_SHIFTS if shifts == "zero" else None)
    s = with_target(s, grasp.Target(kind, float(offset_mm)))
    if step is not None:
        s = with_catch_time_step(s, step)
    return s


_CACHE = {}


def first_plan(scenario_key, scenario, obj, ik, model, predictor):
    """The first-throw plan and the network's cell (as `learn` makes
    them), kept per (object, target, shifts)."""
    if scenario_key not in _CACHE:
        phase = _Phase(scenario, obj, model, ik, prior=None,
                       at_release=False, meshcat=None, on_episode=None,
                       progress=None, planner=PAPER_NETWORK)
        phase.plan_first(predictor)
        _CACHE[scenario_key] = (phase.plan, phase.search.next_cell,
                                phase.predicted)
    return _CACHE[scenario_key]


def catch(name, kind, offset_mm, shifts, cell=None, step=None, *, ik, model,
          predictor):
    obj = resolve_object(name=name)
    scenario = scenario_for(kind, offset_mm, shifts)
    plan, net_cell, predicted = first_plan((name, kind, offset_mm, shifts),
                                           scenario, obj, ik, model, predictor)
    if step is not None:
        scenario = scenario_for(kind, offset_mm, shifts, step)
    cell = tuple(net_cell if cell is None else cell)
    params = cell_parameters(cell)
    start = start_grasp(scenario, obj)
    rec = Recorder(obj, start.R_PO)
    CURRENT["recorder"] = rec
    correction = ReleaseCorrection()
    t0 = time.perf_counter()
    result = episode_module.run_episode(
        scenario, obj, ik=ik, X_WG=plan.X_WG, catch_parameters=params,
        throw_number=1, at_release=release_correction(
            scenario, obj, ik, plan, params, correction))
    CURRENT["recorder"] = None
    wall = time.perf_counter() - t0
    planned = planned_grasp(scenario, obj, plan.catch_point, plan.X_WG)
    row = summarise(rec, result, obj)
    row.update({
        "object": name, "target": f"{kind}{offset_mm:+g}", "shifts": shifts,
        "cell": list(cell), "net_cell": list(net_cell),
        "h_catch": params[0], "h_down": params[1],
        "step_ms": 1e3 * scenario.catch_time_step_s, "predicted": predicted,
        "side": plan.side, "correction": correction.as_dict(),
        "planned_offset_mm": round(planned.offset_mm, 2),
        "planned_tilt_deg": round(planned.tilt_deg, 2),
        "outcome": result.outcome, "success": result.success,
        "achieved": result.achieved_grasp, "error": result.grasp_error,
        "drop_reason": result.drop_reason, "wall_s": round(wall, 2)})
    return row, rec


def summarise(rec, result, obj):
    """The figures of one recorded catch."""
    rows = rec.rows
    t = np.array([r["t"] for r in rows])
    out = {"n_steps": len(rows)}
    phase_t = result.logs.t
    lower = np.flatnonzero(result.logs.phase == int(Phase.LOWER))
    t_close = float(phase_t[lower[0]]) if lower.size else None
    out["t_close"] = t_close
    k = next((i for i, r in enumerate(rows) if r["contacts"]), None)
    if k is None:
        out["contact"] = None
        return out
    r = rows[k]
    # the step before the first contact: the approach
    b = rows[k - 1] if k > 0 else r
    first = r["contacts"]
    palm_first = [c for c in first if c[0] == "palm"]
    bodies = sorted({c[0] for c in first})
    # which end: the first contacts' mean position along the object's axis
    # from its centre of mass (object frame y - h_cm), and along the palm's y
    # from the COM
    y_O = np.mean([c[1][1] for c in first]) - obj.h_cm
    y_P_rel = np.mean([c[2][1] for c in first]) - r["p_PCm"][1]
    kf = next((i for i, q in enumerate(rows[k:], k) if q["contacts"] and any(
        c[0] != "palm" for c in q["contacts"])), None)
    kp = next((i for i, q in enumerate(rows[k:], k) if q["contacts"] and any(
        c[0] == "palm" for c in q["contacts"])), None)
    out["contact"] = {
        "t": r["t"], "bodies": bodies,
        "t_palm": None if kp is None else rows[kp]["t"],
        "t_finger": None if kf is None else rows[kf]["t"],
        "v_n": b["v_rel"][2], "v_y": b["v_rel"][1], "v_x": b["v_rel"][0],
        "w_x": b["w_rel"][0], "w_y": b["w_rel"][1], "w_z": b["w_rel"][2],
        "com_y_mm": 1e3 * b["p_PCm"][1], "com_x_mm": 1e3 * b["p_PCm"][0],
        "com_z_mm": 1e3 * b["p_PCm"][2],
        "offset_mm": b["offset_mm"], "tilt_deg": b["tilt_deg"],
        "axis": b["axis"],
        "v_palm": list(b["v_palm_P"]), "w_palm": list(b["w_palm_P"]),
        "first_end_O_mm": 1e3 * y_O, "first_end_P_mm": 1e3 * y_P_rel,
        "first_on_palm": bool(palm_first)}
    fin = rows[-1]
    out["final"] = {"com_y_mm": 1e3 * fin["p_PCm"][1],
                    "com_x_mm": 1e3 * fin["p_PCm"][0],
                    "offset_mm": fin["offset_mm"], "tilt_deg": fin["tilt_deg"],
                    "axis": fin["axis"], "t": fin["t"]}
    # a short trace around the contact for the plot: -50 ms .. +400 ms
    sel = [i for i in range(len(rows)) if -0.05 <= t[i] - r["t"] <= 0.4]
    sel = sel[::max(1, len(sel) // 200)]
    out["trace"] = {"dt": [round(t[i] - r["t"], 5) for i in sel],
                    "com_y_mm": [round(1e3 * rows[i]["p_PCm"][1], 2)
                                 for i in sel],
                    "offset_mm": [round(rows[i]["offset_mm"], 2) for i in sel],
                    "tilt_deg": [round(rows[i]["tilt_deg"], 2) for i in sel]}
    return out


def jsonable(x):
    if isinstance(x, dict):
        return {k: jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [jsonable(v) for v in x]
    if isinstance(x, (np.floating, float)):
        return round(float(x), 5)
    if isinstance(x, np.integer):
        return int(x)
    if isinstance(x, np.ndarray):
        return jsonable(x.tolist())
    return x


TABLE1 = [f"table1-row{i}" for i in range(1, 6)]
HOLDOUT = ["holdout-dumbbell-d300", "holdout-mallet-d280",
           "holdout-scraper-d330"]


def cases(which):
    out = []
    if which in ("main", "all"):
        for shifts in ("shipped", "zero"):
            for name in TABLE1 + HOLDOUT:
                for kind in ("keep", "flip"):
                    out.append((name, kind, 0, shifts, None, None))
    if which in ("offsets", "all"):
        for shifts in ("shipped", "zero"):
            for name in ("table1-row2", "holdout-mallet-d280"):
                for kind in ("keep", "flip"):
                    for off in (-30, 30):
                        out.append((name, kind, off, shifts, None, None))
    if which in ("cells", "all"):
        for shifts in ("shipped", "zero"):
            for name in ("table1-row2", "table1-row4"):
                for cell in ((2, 3), (5, 12), (9, 1)):
                    out.append((name, "flip", 0, shifts, cell, None))
    if which in ("fine", "all"):
        for name, kind, shifts in (("table1-row1", "keep", "zero"),
                                   ("table1-row2", "flip", "zero"),
                                   ("table1-row2", "flip", "shipped"),
                                   ("table1-row3", "keep", "zero"),
                                   ("table1-row4", "flip", "zero"),
                                   ("table1-row5", "keep", "shipped"),
                                   ("holdout-mallet-d280", "flip", "zero"),
                                   ("holdout-scraper-d330", "keep", "zero")):
            out.append((name, kind, 0, shifts, None, 0.00025))
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--set", default="main")
    ap.add_argument("--out", default="studies/landing/rows.jsonl")
    ap.add_argument("--part", default="0/1", help="k/n: every n-th case")
    ap.add_argument("--plot")
    ap.add_argument("--table", action="store_true",
                    help="print the markdown tables of --out's rows")
    args = ap.parse_args()
    if args.table:
        table(args.out)
        return
    if args.plot:
        plot(args.out, args.plot)
        return
    k, n = map(int, args.part.split("/"))
    ik = ArmIk(load_scenario().directives)
    model, _ = load_weights(MODELS_DIR / load_scenario().catch.weights)
    predictor = FlightPredictor.load(MODELS_DIR / "flight_predictor.json")
    todo = cases(args.set)[k::n]
    for name, kind, off, shifts, cell, step in todo:
        try:
            row, _ = catch(name, kind, off, shifts, cell, step, ik=ik,
                           model=model, predictor=predictor)
        except Exception as e:  # noqa: BLE001  (refused: no plan)
            row = {"object": name, "target": f"{kind}{off:+g}",
                   "shifts": shifts, "cell": cell, "step_ms":
                   None if step is None else 1e3 * step,
                   "error_text": str(e)[:300]}
        with open(args.out, "a") as f:
            f.write(json.dumps(jsonable(row)) + "\n")
        c = row.get("contact") or {}
        print(f"{name} {kind}{off:+g} {shifts} cell {row.get('cell')} step "
              f"{row.get('step_ms')}: {row.get('outcome')} "
              f"{row.get('achieved')} v_n {c.get('v_n', float('nan')):.2f} "
              f"w_x {c.get('w_x', float('nan')):.2f} com_y "
              f"{c.get('com_y_mm', float('nan')):.1f} "
              f"wall {row.get('wall_s')}", flush=True)


def _key(r):
    return (r["object"], r["target"], r["shifts"], tuple(r["cell"]))


def _grasp(a, outcome):
    return (f"{a['offset_mm']:+.1f}/{a['tilt_deg']:.0f}" if a
            else outcome.replace("dropped", "drop"))


def table(rows_path):
    """The compact table (+0 targets, network cell, shipped -> zero shifts)
    and the full one (every 1 ms catch, its 0.25 ms rerun if any)."""
    rows = [json.loads(line) for line in open(rows_path)]
    fine = {_key(r): r for r in rows if r["step_ms"] == 0.25}
    base = {_key(r): r for r in rows if r["step_ms"] == 1.0}
    print("| object | target | cell | v_n | v_y | w_x | first end | "
          "plan S→0 | off@contact S→0 | tilt@c | final off/tilt S → 0 |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        if (r["step_ms"] != 1.0 or r["shifts"] != "shipped"
                or r["cell"] != r["net_cell"] or r["target"][-2:] != "+0"):
            continue
        z = base.get((r["object"], r["target"], "zero", tuple(r["cell"])))
        if z is None:
            z = next(q for q in rows if q["object"] == r["object"]
                     and q["target"] == r["target"] and q["shifts"] == "zero"
                     and q["cell"] == q["net_cell"] and q["step_ms"] == 1.0)
        c, cz = r["contact"], z["contact"]
        print(f"| {r['object'].replace('holdout-', '')} | {r['target']} | "
              f"{tuple(r['cell'])} | {c['v_n']:.2f} | {c['v_y']:+.2f} | "
              f"{c['w_x']:.1f} | {c['first_end_P_mm']:+.0f} | "
              f"{r['planned_offset_mm']:+.0f}→{z['planned_offset_mm']:+.0f} | "
              f"{c['offset_mm']:+.1f}→{cz['offset_mm']:+.1f} | "
              f"{c['tilt_deg']:.0f} | {_grasp(r['achieved'], r['outcome'])} → "
              f"{_grasp(z['achieved'], z['outcome'])} |")
    print()
    print("| object | target | shifts | cell | plan | v_n | v_y | w_x | "
          "COM y@c | off@c | final | 0.25 ms |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        if r["step_ms"] != 1.0:
            continue
        c, f = r["contact"], fine.get(_key(r))
        print(f"| {r['object']} | {r['target']} | {r['shifts']} | "
              f"{tuple(r['cell'])}{'' if r['cell'] == r['net_cell'] else ' o'}"
              f" | {r['planned_offset_mm']:+.0f} | {c['v_n']:.2f} | "
              f"{c['v_y']:+.2f} | {c['w_x']:.1f} | {c['com_y_mm']:+.1f} | "
              f"{c['offset_mm']:+.1f} | {_grasp(r['achieved'], r['outcome'])}"
              f" | {_grasp(f['achieved'], f['outcome']) if f else ''} |")


def plot(rows_path, png):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    rows = [json.loads(line) for line in open(rows_path)]
    rows = [r for r in rows if r.get("contact") and r["step_ms"] == 1.0]
    fig, ax = plt.subplots(1, 3, figsize=(16, 5))
    for r in rows:
        if r["cell"] != r["net_cell"] or r["target"][-2:] != "+0":
            continue
        tr = r["trace"]
        ax[0].plot(1e3 * np.array(tr["dt"]), tr["offset_mm"],
                   color="C0" if r["shifts"] == "shipped" else "C1",
                   lw=0.8, alpha=0.7)
    ax[0].axvline(0, color="k", lw=0.5)
    ax[0].axhspan(-10, 10, color="g", alpha=0.1)
    ax[0].set_xlabel("time from first contact [ms]")
    ax[0].set_ylabel("grasp offset (palm centre along object axis) [mm]")
    ax[0].set_title("+0 mm targets, network cell: blue shipped shifts, "
                    "orange shifts 0", fontsize=9)
    ax[0].set_ylim(-60, 60)
    for r in rows:
        if r["outcome"] not in ("caught", "wrong_grasp"):
            continue
        c = r["contact"]
        tgt = float(r["target"][4:])
        e0 = c["offset_mm"] - tgt
        e1 = r["achieved"]["offset_mm"] - tgt
        m = "o" if r["shifts"] == "shipped" else "s"
        col = "C3" if r["target"].startswith("flip") else "C2"
        ax[1].scatter(e0, e1, marker=m, color=col, s=18)
        ax[2].scatter(abs(c["v_y"]), r["achieved"]["tilt_deg"], marker=m,
                      color=col, s=18)
    lim = [-40, 40]
    ax[1].plot(lim, lim, "k", lw=0.5)
    ax[1].axhspan(-10, 10, color="g", alpha=0.1)
    ax[1].set_xlabel("offset error at first contact [mm]")
    ax[1].set_ylabel("final offset error [mm]")
    ax[1].set_title("held catches: red flip, green keep; o shipped, "
                    "s shifts 0", fontsize=9)
    ax[2].axhline(20, color="k", lw=0.5)
    ax[2].set_xlabel("|object speed along palm y| at contact [m/s]")
    ax[2].set_ylabel("final tilt [deg] (tilt at contact: 0-8 deg)")
    fig.tight_layout()
    fig.savefig(png, dpi=110)


if __name__ == "__main__":
    main()
