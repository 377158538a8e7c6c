"""Success maps over the parameter space (parameter_space.py), and their rows
(written and read by map_rows.py).

A success map runs one catch episode per cell. The cells share one simulated
throw up to the moment their parameters are first read, and fork from there
(episode/branching.py), `workers` at a time; each result is written as a JSON
line as soon as it is known, and a run resumes from that file.
"""

import json
import multiprocessing
from pathlib import Path

import torch

from regrasp_drake import atomic_io
from regrasp_drake.episode.branching import run_cells
from regrasp_drake.errors import InputError, check_interrupt
from regrasp_drake.input_files import load_json
from regrasp_drake.map_rows import open_rows, plan_path, read_rows
from regrasp_drake.parameter_space import (  # noqa: F401 (nearest_cell: re-exported)
    ENDINGS,
    H_CATCH_VALUES,
    H_DOWN_VALUES,
    HELD_OUTCOMES,
    cell_parameters,
    cells,
    nearest_cell,
)
from regrasp_drake.planning.follow import plan_follow
from regrasp_drake.planning.ik import ArmIk
from regrasp_drake.progress import bar as progress_bar
from regrasp_drake.station.scenario import load_scenario, scenario_digest
from regrasp_drake.throw_catch import plan_at_moment, watch
from regrasp_drake.world.objects import resolve_object
from regrasp_drake.world.robot import ARM_LINKS, FINGER_LINKS


# ---- success maps ----------------------------------------------------------
def plan_object(scenario, obj, ik, catch_point: int = 1):
    """The watching throw and the offline stage (deterministic): the plan at
    the `catch_point`-th catch point, counted as the data set counts them
    (reachable moments, best first, at least CATCH_POINT_SEPARATION_S
    apart). Raises InputError when the flight has fewer."""
    return plan_at_moment(scenario, obj, ik, watch(scenario, obj, ik),
                          catch_point, field="--catch-point")


def append_rows(function, tasks, path: Path, done: dict, key, *,
                workers: int, label: str, unit: str) -> None:
    """Runs function(task) for every task in `workers` forked processes and
    appends each result row to the JSON-lines file at path as it finishes
    (fsynced, in the tasks' order), into `done` under key(row) too, with a
    progress bar: a killed run resumes with read_rows(path, key)."""
    ctx = multiprocessing.get_context("fork")
    with (ctx.Pool(workers) as pool, open_rows(path) as f,
          progress_bar(len(tasks), label, unit) as shown):
        for row in pool.imap(function, tasks):
            check_interrupt()
            f.append(json.dumps(row))
            done[key(row)] = row
            shown.update()


def run_map(scenario, obj, ik, plan, out: Path, *, workers: int = 1,
            progress=True, only=None) -> dict:
    """Runs every cell of `obj`'s success map not yet in `out` (JSON lines,
    appended and fsynced as each cell finishes); returns {cell: row}.

    The cells share one simulated throw up to their triggers (see
    episode/branching.py); `workers` simulations run at once. `only`: a
    subset of the cells (a coarse map), default all. The palm follows the
    object as the scenario's catch mode has it (catch.follow_pitch,
    catch.follow_along; planning/follow.plan_follow): a map in a catch
    mode."""
    out = Path(out)
    done = read_rows(out)
    wanted = cells() if only is None else [tuple(c) for c in only]
    todo = [c for c in wanted if c not in done]
    if not todo:
        return done
    with (open_rows(out) as f,
          progress_bar(len(todo), obj.name, enabled=progress) as shown):
        def write(i, result):
            row = {"cell": list(todo[i])} | result.cell_row()
            f.append(json.dumps(row))
            done[todo[i]] = row
            shown.update()
        run_cells(scenario, obj, ik=ik, X_WG=plan.X_WG,
                  parameters=[cell_parameters(c) for c in todo],
                  workers=workers, on_result=write,
                  follow=plan_follow(scenario, obj, plan.catch_point,
                                     plan.X_WG))
    return done


def success_map(*, object_name=None, object_file=None, scenario=None,
                out: Path, workers: int = 2, progress=True,
                catch_point: int = 1) -> dict:
    """`regrasp-drake grid`: the success map of one object at its
    `catch_point`-th catch point, resumable. What the rows are computed from
    (the object, the catch point, the scenario's digest and the plan) is
    written beside them (`plan_path`) and must match when a run resumes.
    scenario: a Scenario (default: the shipped one). One run at a time
    computes a map (map_lock)."""
    torch.set_num_threads(1)
    scenario = scenario or load_scenario()
    obj = resolve_object(name=object_name, file=object_file)
    ik = ArmIk(scenario.directives)
    with map_lock(out):  # before the watching throw: a refusal is at once
        plan = plan_object(scenario, obj, ik, catch_point)
        check_resume(out, map_source(scenario, obj, catch_point, plan))
        return run_map(scenario, obj, ik, plan, out, workers=workers,
                       progress=progress)


def map_lock(out: Path):
    """The lock a run holds while it computes the map at `out` (F.lock
    beside it): a second run on it is refused (atomic_io.LockedError naming
    the first's pid and host)."""
    out = Path(out)
    return atomic_io.exclusive(out.with_name(out.name + ".lock"),
                               what=f"map {out}", wait=False)


def map_source(scenario, obj, catch_point: int, plan) -> dict:
    """What a success map's rows are computed from."""
    return {"object": obj.name, "catch_point": catch_point,
            "scenario_digest": scenario_digest(scenario),
            "plan": plan.as_dict()}


def check_resume(out: Path, source: dict, flag: str = "--out") -> None:
    """Before rows are appended to `out`: writes `source` to plan_path(out)
    for a new map; for a map begun earlier, refuses (InputError naming
    `flag`, the argument that named the map) rows computed from anything
    else (another object, catch point, scenario or plan), which resuming
    would mix into this map."""
    out, side = Path(out), plan_path(out)
    if side.exists():
        try:
            stored = load_json(side)
        except InputError as e:
            raise InputError(f"{flag}: {e}, expected what the map's rows "
                             "were computed from") from None
        if not isinstance(stored, dict):
            raise InputError(f"{flag}: {side}: not a JSON mapping, expected "
                             "what the map's rows were computed from")
        if stored != source:
            differs = [k for k in source if stored.get(k) != source[k]]
            raise InputError(
                f"{flag}: {out} holds a map of {stored.get('object')} at "
                f"catch point {stored.get('catch_point')} computed with "
                f"another {', '.join(differs)} ({side}), expected one of "
                f"{source['object']} at catch point {source['catch_point']} "
                f"with this scenario: give another {flag}")
        return
    if read_rows(out):
        raise InputError(
            f"{flag}: {out} holds cells but no {side.name} saying what they "
            "were computed from, expected a new file or one this command "
            f"began: give another {flag}")
    atomic_io.write_json(side, source)


def ending(row: dict) -> str:
    """The key of ENDINGS that describes a map row (the finger and arm
    bodies of world/robot.py tell where a dropped object lies)."""
    if row["outcome"] in ("caught", "wrong_grasp", "failed"):
        return row["outcome"]
    reason = row.get("drop_reason")
    if row["outcome"] != "dropped" or reason is None:
        return "other"
    if reason != "not_held":
        return reason
    touching = set(row.get("touching") or ())
    if touching & {b for links in FINGER_LINKS.values() for b in links}:
        return "in_fingers"
    if touching & set(ARM_LINKS):
        return "on_arm"
    return "loose"


def ending_counts(rows) -> dict:
    """{ENDINGS key: how many of the rows (an iterable) end so}, every key
    present."""
    counts = dict.fromkeys(ENDINGS, 0)
    for row in rows:
        counts[ending(row)] += 1
    return counts


def disagreements(rows: dict) -> dict:
    """{cell: row} of the map rows whose grasp monitor's verdict (caught or
    not) differs from the plant's contact results' (`held_by_contact`);
    rows without the latter (older files, failed contact solves) are left
    out."""
    return {cell: row for cell, row in rows.items()
            if row.get("held_by_contact") is not None
            and (row["outcome"] in HELD_OUTCOMES) != row["held_by_contact"]}


def format_map(rows: dict) -> str:
    """A ✓/✗ grid: rows h_catch (m), columns h_down (cm); ? not yet run;
    then how many cells catch, how the others ended (`ending`), and the
    cells where the contacts disagree with the monitor (`disagreements`)."""
    lines = ["h_catch m \\ h_down cm " + " ".join(f"{d * 100:>3.0f}"
                                                for d in H_DOWN_VALUES)]
    for i, h_catch in enumerate(H_CATCH_VALUES):
        marks = []
        for j in range(len(H_DOWN_VALUES)):
            row = rows.get((i, j))
            marks.append("?" if row is None else
                         "✓" if row["outcome"] == "caught" else "✗")
        lines.append(f"{h_catch:>20.2f}  " + " ".join(f"{m:>3}" for m in marks))
    caught = sum(r["outcome"] == "caught" for r in rows.values())
    lines.append(f"{caught}/{len(rows)} cells catch")
    counts = ending_counts(rows.values())
    for key, n in counts.items():
        if key != "caught" and n:
            lines.append(f"  {n:>3} {ENDINGS[key]}")
    differ = disagreements(rows)
    if differ:
        lines.append(f"{len(differ)} cell(s) where the contacts disagree with "
                     "the grasp monitor (held by contact: "
                     + ", ".join(f"{list(c)} {r['held_by_contact']}"
                                 for c, r in sorted(differ.items())) + ")")
    return "\n".join(lines)
