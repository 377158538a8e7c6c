"""The paper's Table 1 reproduced: the learning phase on its five test
objects with the shipped network, our figures beside the paper's."""

import sys
from pathlib import Path

import numpy as np

from regrasp_drake import atomic_io, grid
from regrasp_drake import progress as progress_lines
from regrasp_drake.learning.learning_phase import NoCatchPoint, learn
from regrasp_drake.learning.library import load_library
from regrasp_drake.learning.plots import plot_search
from regrasp_drake.throw_catch import plan_catch, watch
from regrasp_drake.world.objects import resolve_object

# Table 1 of the paper: row, object ID, density (kg/m³), centre of mass
# (x, y, z in the object frame, m), time (s), number of trials.
PAPER_TABLE1 = [
    (1, 1, 150, (0.000, -0.010, 0.000), 68, 3),
    (2, 1, 200, (0.000, -0.010, 0.000), 44, 2),
    (3, 1, 200, (0.000, -0.020, 0.000), 68, 3),
    (4, 2, 300, (0.000, -0.055, 0.043), 42, 2),
    (5, 2, 350, (0.000, -0.055, 0.043), 42, 2),
]


def object_names(objects=None) -> list[str]:
    """The objects of the table: `objects` (catalogue names), by default
    the paper's five, table1-row1 … row5."""
    return list(objects or [f"table1-row{r[0]}" for r in PAPER_TABLE1])


def map_paths(maps_dir, name: str) -> tuple[Path, Path]:
    """The success map (JSON lines, with its plan beside it as grid writes
    it) and the PNG of object `name` under maps_dir."""
    return Path(maps_dir) / f"{name}.jsonl", Path(maps_dir) / f"{name}.png"


def run_table1(scenario, model, *, ik, library_path=None, maps_dir=None,
               map_workers: int = 2, progress=sys.stderr,
               flight_predictor=None, objects=None,
               max_throws=None, at_release: bool = False,
               search: str = "wavefront", offset_prior=None,
               planner=None, rehearse: bool = False) -> list[dict]:
    """Runs the learning phase on table1-row1 … row5 (or on `objects`, names
    of other catalogue objects); returns one row each. With maps_dir: also
    each object's full success map (resumable JSON lines) and a PNG of it
    with the network's start cell and the search path. flight_predictor:
    the first-throw mode (no watching throw); at_release: the first-throw
    mode that plans each throw at its release; search: the learning phase's
    search after the network's cell, "wavefront" (the paper's) or
    "map-prior" (learning/search.py); planner, rehearse: learn's (None: the
    target's shipped planner); offset_prior: learn's, for a
    regrasp target."""
    if library_path is not None:
        load_library(library_path)  # a malformed file: refused before any throw
    rows = []
    first_throw = flight_predictor is not None or at_release
    names = object_names(objects)
    by_name = {f"table1-row{r[0]}": r for r in PAPER_TABLE1}
    # A Table 1 object keeps its row and the paper's figures.
    paper = [by_name.get(name, (k + 1, None, None, None, None, None))
             for k, name in enumerate(names)]
    for (row, obj_id, density, com, time_s, trials), name in progress_lines.iterate(
            zip(paper, names), len(names), "Table 1", "objects",
            enabled=progress is not None):
        obj = resolve_object(name=name)
        try:
            result = learn(scenario, obj, model, ik=ik,
                           library_path=library_path, progress=progress,
                           flight_predictor=flight_predictor,
                           max_throws=max_throws, at_release=at_release,
                           search=search, offset_prior=offset_prior,
                           planner=planner, rehearse=rehearse)
        except NoCatchPoint as e:  # the watching throw shows no catch point
            rows.append({"row": row, "object": obj.name,
                         "paper_object_id": obj_id,
                         "first_throw": first_throw,
                         "at_release": at_release, "search": search,
                         "density": obj.d_obj, "h_cm": obj.h_cm,
                         "r_cm": obj.r_cm, "caught": False,
                         "throws": e.throws, "stopped": "no_catch_point",
                         "sim_time_s": round(e.sim_time_s, 2),
                         "wall_s": round(e.wall_s, 1), "error": str(e),
                         "paper": None if obj_id is None else {
                             "density": density, "com": list(com),
                             "time_s": time_s, "trials": trials}})
            if progress is not None:
                progress_lines.say(f"{obj.name}: {e}", progress)
            continue
        entry = {
            "row": row, "object": obj.name, "paper_object_id": obj_id,
            "first_throw": first_throw, "at_release": at_release,
            "search": search, "density": obj.d_obj, "h_cm": obj.h_cm, "r_cm": obj.r_cm,
            "target": result.target, "success": result.success,
            "caught": result.caught, "achieved_grasp": result.achieved_grasp,
            "throws": result.throws,
            "stopped": result.stopped, "replanned": result.replanned,
            "sim_time_s": round(result.sim_time_s, 2),
            "wall_s": round(result.wall_s, 1),
            "features": [round(x, 6) for x in result.features],
            "start_cell": list(result.start_cell),
            "prediction": [round(x, 3) for x in result.prediction],
            "attempts": [a.as_dict() for a in result.attempts],
            "paper": None if obj_id is None else {
                "density": density, "com": list(com), "time_s": time_s,
                "trials": trials},
        }
        if first_throw:
            entry["catch_point_check"] = catch_point_check(
                scenario, obj, ik, result.first_plan or result.plan)
        if maps_dir is not None:
            Path(maps_dir).mkdir(parents=True, exist_ok=True)
            rows_path, png_path = map_paths(maps_dir, obj.name)
            # What the rows are computed from, beside them (as `grid`
            # keeps it): a rerun resumes only the same map.
            with grid.map_lock(rows_path):
                grid.check_resume(rows_path, grid.map_source(
                    scenario, obj, 1, result.plan), flag="--maps-dir")
                cells = grid.run_map(scenario, obj, ik, result.plan,
                                     rows_path, workers=map_workers,
                                     progress=progress is not None)
            entry["cells_caught"] = sum(r["outcome"] == "caught"
                                        for r in cells.values())
            png = plot_search(result.search_attempts, result.start_cell,
                              png_path,
                              title=f"{obj.name}: {result.throws} throws, "
                                    f"{entry['cells_caught']}/150 cells catch",
                              success_map=cells)
            entry["map_png"] = str(png)
        rows.append(entry)
    return rows


def catch_point_check(scenario, obj, ik, planned) -> dict:
    """The first throw's catch point, as planned without watching, beside
    the one a watching throw of the same (deterministic) throw gives: a
    check simulated after the learning phase, not counted in its throws,
    so that a first-throw catch is never a wrong prediction's luck called a
    prediction. The palm offset is the distance between the two planned
    palm positions; the moment, between the two catch times."""
    watched = plan_catch(scenario, obj, ik, watch(scenario, obj, ik))

    def point(plan) -> dict:
        return {"t_s": round(plan.catch_point.t_s, 4),
                "p_WO": [round(float(c), 4) for c in plan.catch_point.p_WO]}

    offset = planned.X_WG.translation() - watched.X_WG.translation()
    # The planned palm in the watched palm's frame G: x across the object's
    # axis, y along it (the frame of benchmarks/catch_tolerance.py's
    # offsets), and the angle between the two palms' orientations.
    X_GP = watched.X_WG.inverse() @ planned.X_WG
    angle = X_GP.rotation().ToAngleAxis().angle()
    return {"planned": point(planned), "watched": point(watched),
            "palm_offset_mm": round(1000.0 * float(
                (offset @ offset) ** 0.5), 1),
            "palm_offset_G_mm": [round(1000.0 * float(c), 1)
                                 for c in X_GP.translation()],
            "palm_angle_deg": round(float(np.degrees(angle)), 2),
            "moment_ms": round(1000.0 * abs(
                planned.catch_point.t_s - watched.catch_point.t_s), 1)}


def format_markdown(rows: list[dict]) -> str:
    """The table in Markdown, ours beside the paper's."""
    lines = [
        "| Row | Object | Density kg/m³ | CoM (h_cm, r_cm) m | Throws (paper) "
        "| Throws (ours) | Time s (paper) | Sim time s (ours) | Wall s (ours) "
        "| Caught |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        p = r["paper"] or {"trials": "–", "time_s": "–"}
        lines.append(
            f"| {r['row']} | ({r['paper_object_id'] or '–'}) {r['object']} "
            f"| {r['density']:.0f} | ({r['h_cm']:.3f}, {r['r_cm']:.3f}) "
            f"| {p['trials']} | {r['throws']} | {p['time_s']} "
            f"| {r['sim_time_s']:.1f} | {r['wall_s']:.1f} "
            f"| {'yes' if r['caught'] else 'no'} |")
    checks = [r for r in rows if r.get("catch_point_check")]
    if checks:
        lines += ["", "Catch point planned without watching against a watching "
                      "throw's (a check, not counted in the throws):", "",
                  "| Object | Planned t s, p_WO m | Watched t s, p_WO m "
                  "| Palm offset mm | (across, along, normal) mm "
                  "| Palm angle deg | Moment ms |",
                  "|---|---|---|---|---|---|---|"]
        for r in checks:
            c = r["catch_point_check"]
            lines.append(
                f"| {r['object']} | {c['planned']['t_s']:.3f}, "
                f"{c['planned']['p_WO']} | {c['watched']['t_s']:.3f}, "
                f"{c['watched']['p_WO']} | {c['palm_offset_mm']:.1f} "
                f"| {tuple(c['palm_offset_G_mm'])} | {c['palm_angle_deg']:.1f} "
                f"| {c['moment_ms']:.1f} |")
    searches = sorted({r.get("search", "wavefront") for r in rows})
    if searches != ["wavefront"]:
        lines += ["", f"Search after the network's cell: {', '.join(searches)}"
                      " (the paper's is the wavefront)."]
    return "\n".join(lines)


def write_outputs(rows, json_path=None, markdown_path=None) -> None:
    if json_path is not None:
        atomic_io.write_json(json_path, rows)
    if markdown_path is not None:
        atomic_io.write_text(markdown_path, format_markdown(rows) + "\n")
