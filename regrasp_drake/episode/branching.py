"""Every cell of the parameter space from one shared throw, by forking the
simulation where the cells' histories part.

Until the catch state machine first compares the approach sensors with
h_catch, a catch episode does not depend on (h_catch, h_down) at all: the
throw, the move to the grasp position and the wait are the same simulation
for every cell. A cell's history parts from the others at its trigger: the
first sensor sample in WAIT at which the approach distance is below its
h_catch (h_down is read there too; neither is read again). Cells whose rows
trigger at the same sample with the same h_down are therefore one and the
same simulation, run once. So one parent simulation runs the shared
history with a parameter that never triggers (h_catch = 0), and at each
sample checks, before the state machine's update at that time runs, which
rows of h_catch would trigger now; for each such cell it forks the process
(`os.fork`: the child holds the parent's simulator and context, bit for bit),
and the child sets the cell's parameters and runs to the outcome. A cell
whose h_catch never triggers shares the parent's outcome, computed with
parameters it never read.

The result of each cell is the result that `run_episode` gives for it (the
tests compare them): this only skips recomputing the shared part.
"""

import dataclasses as dc
import os
import pickle
import signal
import time
import traceback

import numpy as np

from regrasp_drake.episode.episode import Episode
from regrasp_drake.episode.result import EpisodeResult, read_result
from regrasp_drake.errors import check_interrupt
from regrasp_drake.station.catch_state_machine import Phase


def run_cells(scenario, obj, *, ik, X_WG, parameters, workers: int = 1,
              on_result=None, throws=None, follow=None) -> list[EpisodeResult]:
    """Runs one catch episode per (h_catch, h_down) in `parameters`.

    Returns one EpisodeResult per entry, in order, as `run_episode` gives
    it but without logs (episode.read_result); its wall_s is the child's
    wall time, or the shared run's for cells that never triggered.
    `on_result(i, result)` is called as each cell finishes. At most `workers`
    children run at once.
    With a catch step of its own (scenario.catch_time_step_s), the shared
    run is handed over to it at the release time (episode.hand_over), as
    `run_episode`'s; `throws` and `follow` as run_episode's (default:
    THROWS; no follow).
    """
    t0 = time.perf_counter()
    parameters = [(float(h), float(d)) for h, d in parameters]
    shared = _shared_run(scenario, obj, ik, X_WG, throws, follow)
    t_final = shared.scenario.monitor.max_time_s + 1.0
    rows = [None] * len(parameters)

    def report(indices, result):
        for i in indices:
            h_catch, h_down = parameters[i]
            rows[i] = dc.replace(result, h_catch=h_catch, h_down=h_down)
            if on_result is not None:
                on_result(i, rows[i])

    def died():
        return EpisodeResult(
            object=obj.name, outcome="failed", h_catch=None, h_down=None,
            sim_time_s=None, wall_s=None, build_s=0.0, catch_time_s=None,
            message="the simulation process died", logs=None)

    def fork(group):
        """A child process runs the first cell of `group` from here to its
        outcome; it is the outcome of every cell in the group (see
        `_run_to_triggers`)."""
        children.start(group, lambda: _run_child(
            shared, parameters[group[0]], t_final))

    children = _Children(workers, report, died)
    try:
        message, waiting = _run_to_triggers(shared, parameters, t_final,
                                            fork)
        # Cells that never triggered share the parent's history to its end.
        never = [i for i, (h, _) in enumerate(parameters) if h in waiting]
        if never:
            if not message and shared.outcome() == "running":
                message = shared.advance_to_outcome(t_final)
            report(never, _read_cell(shared, message, None,
                                     time.perf_counter() - t0))
        children.finish_all()
    except BaseException:
        children.kill_all()  # interrupted (Ctrl-C) or failed
        raise
    return rows


def _shared_run(scenario, obj, ik, X_WG, throws, follow=None) -> Episode:
    """The episode the cells share, at the release time when handed over
    there (or at the start): the throw
    simulated before by the watching throw the plan came from
    (episode.ThrowCache), or simulated here and kept; its parameters
    (0, 0) never trigger."""
    shared = Episode(scenario, obj, ik=ik, X_WG=X_WG,
                     catch_parameters=(0.0, 0.0), throws=throws, follow=follow)
    shared.start()
    simulator, episode = shared.simulator, shared.diagram
    if shared.handover.before is not None:
        machine = episode.controller.state_machine
        phase = machine.GetOutputPort("phase").Eval(
            machine.GetMyContextFromRoot(simulator.get_context()))[0]
        if phase >= Phase.WAIT:
            raise ValueError("the hand already waits at the release time "
                             "(a cell may have triggered)")
    return shared


def _run_to_triggers(shared: Episode, parameters, t_final,
                     fork) -> tuple[str, list]:
    """Advances the shared run sample by sample until every row of h_catch
    has triggered (or the run ends), calling fork(indices) for the cells
    that part from it at each sample, before the state machine's update at
    that time runs. Returns the run's failure message ("" if none) and the
    h_catch values that never triggered."""
    sensors = shared.scenario.sensors
    waiting = sorted({h for h, _ in parameters}, reverse=True)
    message = ""
    # 0, or the release's
    k = round(shared.simulator.get_context().get_time() / sensors.period_s)
    while waiting:
        check_interrupt()
        k += 1
        message = shared.advance_to_outcome(min(k * sensors.period_s,
                                                t_final))
        # The diagram it runs in (another from the landing's handover on).
        ir_levels = shared.diagram.station.GetOutputPort("ir_levels")
        machine = shared.diagram.controller.state_machine
        context = shared.simulator.get_context()
        if (message or shared.outcome() != "running"
                or context.get_time() >= t_final):
            break
        phase = machine.GetOutputPort("phase").Eval(
            machine.GetMyContextFromRoot(context))[0]
        if phase != Phase.WAIT:
            continue
        ir_context = ir_levels.get_system().GetMyContextFromRoot(context)
        # What the state machine's check at this time will read.
        distance = (float(np.min(ir_levels.Eval(ir_context)[3:]))
                    / sensors.levels * sensors.approach_range_m)
        triggered = []
        while waiting and distance < waiting[0]:
            triggered.append(waiting.pop(0))
        # Rows that trigger at the same sample share their history to
        # here, and h_catch is never read again: cells with the same
        # h_down are one simulation.
        for h_down in sorted({d for h, d in parameters if h in triggered}):
            fork([i for i, (h, d) in enumerate(parameters)
                  if h in triggered and d == h_down])
    return message, waiting


class CellError(Exception):
    """An exception a forked cell's process raised (only Drake's solver
    failure is an outcome, episode/diagram.py), raised again in the
    parent; its message is the child's traceback."""


class _Children:
    """The forked children running cells, at most `workers` at once. Each
    sends its EpisodeResult through a pipe; report(indices, result) is
    called as each finishes (with died() for one that sent nothing)."""

    def __init__(self, workers: int, report, died):
        self._workers = max(1, workers)
        self._report, self._died = report, died
        self._running = {}  # pid -> (read end, indices)

    def start(self, indices, run) -> None:
        """Forks a child that sends run()'s result for `indices`."""
        while len(self._running) >= self._workers:
            self._finish_one()
        read_fd, write_fd = os.pipe()
        # Ctrl-C held back over the fork until the child is on record:
        # arriving during it, its handler would run inside an at-fork hook
        # (logging's), which swallows the KeyboardInterrupt; held back, it is
        # raised right after, here, and the child is killed (kill_all).
        mask = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
        pid = os.fork()
        if pid == 0:
            try:
                signal.pthread_sigmask(signal.SIG_SETMASK, mask)
                os.close(read_fd)
                try:
                    result = run()
                except Exception:  # raised again in the parent
                    result = CellError(traceback.format_exc())
                with os.fdopen(write_fd, "wb") as f:
                    f.write(pickle.dumps(result))
            finally:
                os._exit(0)
        os.close(write_fd)
        self._running[pid] = (read_fd, indices)
        signal.pthread_sigmask(signal.SIG_SETMASK, mask)
        check_interrupt()  # one that another thread took, lost in the fork

    def finish_all(self) -> None:
        while self._running:
            self._finish_one()

    def _finish_one(self) -> None:
        pid = next(iter(self._running))
        fd, indices = self._running[pid]
        with os.fdopen(fd, "rb", closefd=False) as f:
            data = f.read()
        os.waitpid(pid, 0)
        os.close(fd)
        del self._running[pid]
        check_interrupt()
        result = pickle.loads(data) if data else self._died()
        if isinstance(result, CellError):
            raise result
        self._report(indices, result)

    def kill_all(self) -> None:
        """No child outlives the command."""
        for pid, (fd, _) in self._running.items():
            try:
                os.kill(pid, signal.SIGKILL)
                os.waitpid(pid, 0)
            except (ChildProcessError, ProcessLookupError):
                pass  # reaped already
            try:
                os.close(fd)
            except OSError:
                pass  # closed already (interrupted in `_finish_one`)
        self._running.clear()


def _run_child(shared: Episode, cell_parameters, t_final) -> EpisodeResult:
    """In a forked child: the cell's parameters set, the shared episode run
    on from the parent's state to its outcome."""
    t0 = time.perf_counter()
    shared.set_task(catch_parameters=cell_parameters)
    message = shared.advance_to_outcome(t_final)
    return _read_cell(shared, message, cell_parameters,
                      time.perf_counter() - t0)


def _read_cell(shared: Episode, message: str, cell_parameters,
               wall_s: float) -> EpisodeResult:
    """A cell's result, without logs, from the shared episode at its end
    (result.read_result); h_catch and h_down are the cell's (None: set by
    the caller)."""
    h_catch, h_down = cell_parameters or (None, None)
    return read_result(shared.diagram, shared.simulator.get_context(),
                       shared.scenario, shared.obj, message=message,
                       h_catch=h_catch, h_down=h_down,
                       wall_s=wall_s)
