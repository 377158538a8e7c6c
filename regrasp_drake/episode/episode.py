"""One episode you can hold, run in stages:

    episode = Episode(scenario, obj, ik=ik, X_WG=X_WG, catch_parameters=h)
    episode.start()                      # built (or a kept throw resumed)
    release = episode.advance_to_release()   # the object at the release
    episode.set_task(X_WG=..., catch_parameters=...)  # the catch planned
    episode.advance_to_outcome()         # until the grasp monitor ends it
    result = episode.result()            # the outcome, the grasp, the logs

`run_episode` is those stages in one call, with an optional `at_release`
plan. The episode's diagram is episode/diagram.py's; advancing it,
episode/simulate.py's; reading its end, episode/result.py's."""

import dataclasses as dc
import time

import numpy as np
from pydrake.math import RigidTransform

from regrasp_drake.episode.diagram import (
    EpisodeDiagram,
    build_episode_diagram,
    fixed_catch_parameters,
)
from regrasp_drake.episode.result import EpisodeResult, read_result, start_grasp
from regrasp_drake.episode.simulate import (
    THROWS,
    Handover,
    ThrowCache,
    advance_to_outcome,
    read_logs,
    read_outcome,
    release_time,
    start_episode,
)
from regrasp_drake.planning.ik import ArmIk
from regrasp_drake.station.scenario import Scenario
from regrasp_drake.world.objects import ObjectSpec


@dc.dataclass(frozen=True)
class Release:
    """The object at the release time, when the catch may still be planned
    (`Episode.set_task`): the state machine reads the grasp pose at the
    first update from here on."""
    t: float                  # the release time, [s]
    object_state: np.ndarray  # (13,): quaternion wxyz, p_WO, w_WO, v_WO


class Episode:
    """One throw of `obj` and, unless X_WG is None (a watching throw), its
    catch, held between the stages of its run (see the module's docstring).

    X_WG: the palm's grasp pose; catch_parameters: (h_catch, h_down), [m],
    or None for the scenario's catch.parameter_source (fixed values, or the
    MLP system fed with `mlp_features`); meshcat records the episode from
    its start; throw_number seeds the release noise, if the scenario has
    any; throws: the cache of throws simulated to their release this
    episode goes on from and keeps its throw in (default: the process's,
    THROWS)."""

    def __init__(self, scenario: Scenario, obj: ObjectSpec, *, ik: ArmIk,
                 X_WG: RigidTransform | None, catch_parameters=None,
                 mlp_features=None, meshcat=None, throw_number: int = 1,
                 throws: ThrowCache | None = None):
        self._t0 = time.perf_counter()
        self.obj, self.ik = obj, ik
        self.X_WG, self.mlp_features = X_WG, mlp_features
        self.meshcat, self.throw_number = meshcat, throw_number
        self.throws = THROWS if throws is None else throws
        # How the object lies on the palm before the throw.
        self.start_grasp = start_grasp(scenario, obj)
        self.catch_parameters = fixed_catch_parameters(scenario, X_WG,
                                                       catch_parameters)
        # The throw's scenario; the catch's (at its plant step) once handed
        # over at the release time.
        self.scenario = scenario
        self.simulator = None
        self.diagram: EpisodeDiagram | None = None
        self.handover: Handover | None = None
        self.message = ""   # a failure's, once the episode failed
        self.build_s = 0.0  # the wall time to build and initialise, [s]
        self._recording = meshcat is not None

    def build(self, scenario: Scenario) -> EpisodeDiagram:
        """The episode's diagram for `scenario` (the throw's, or the
        catch's at the handover)."""
        return build_episode_diagram(
            scenario, self.obj, ik=self.ik, X_WG=self.X_WG,
            catch_parameters=self.catch_parameters,
            mlp_features=self.mlp_features, meshcat=self.meshcat,
            throw_number=self.throw_number)

    def start(self) -> None:
        """Stage 1: the episode built and initialised, or its throw resumed
        from `throws`; handed over at the release time to the catch's plant
        step when the scenario has one (simulate.start_episode)."""
        self.handover, self.build_s = start_episode(
            self.scenario, self.obj, self.build, ik=self.ik, X_WG=self.X_WG,
            catch_parameters=self.catch_parameters,
            throw_number=self.throw_number, meshcat=self.meshcat,
            throws=self.throws)
        # From here on the episode goes on under the catch's scenario.
        self.simulator, self.diagram, self.scenario = self.handover.now
        self.message = self.handover.message

    @property
    def running(self) -> bool:
        """Started, and not ended before the release time."""
        return self.handover is not None and self.handover.running

    def advance_to_release(self) -> Release:
        """Stage 2: the episode at its release time (where a handover left
        it already), and the object's state there."""
        t = release_time(self.scenario)
        if self.simulator.get_context().get_time() < t:  # not handed over
            self.simulator.AdvanceTo(t)
        state = self.diagram.station.Eval("object_state",
                                          self.simulator.get_context())
        return Release(t=t, object_state=np.asarray(state).copy())

    def set_task(self, *, X_WG: RigidTransform | None = None,
                 catch_parameters=None) -> None:
        """Stage 3: the grasp pose and the catch parameters (h_catch,
        h_down), [m], set in the running context (None leaves one as it
        is). Drake handles the update events of a time at the start of the
        next step, so the state machine's update at the release time reads
        them."""
        self.diagram.controller.set_task(
            self.simulator.get_mutable_context(), X_WG=X_WG,
            catch_parameters=catch_parameters)

    def advance_to_outcome(self, t_final: float | None = None) -> str:
        """Stage 4: on until the grasp monitor (or a failure) ends the
        episode, or to t_final, [s]. Returns "" or the failure's message."""
        self.message = advance_to_outcome(self.simulator, self.diagram,
                                          self.scenario, t_final)
        return self.message

    def outcome(self) -> str:
        """What the grasp monitor has decided so far: "running" until the
        episode ends (simulate.read_outcome; a failure is not counted)."""
        return read_outcome(self.diagram, self.simulator.get_context(),
                            "")[0]

    def stop_recording(self) -> None:
        """Meshcat's recording of this episode stopped, once."""
        if self._recording:
            self._recording = False
            self.meshcat.StopRecording()

    def result(self) -> EpisodeResult:
        """Stage 5: what the episode came to (result.read_result), with the
        whole episode's logs; Meshcat's recording published."""
        wall_s = time.perf_counter() - self._t0
        if self._recording:
            self.stop_recording()
            self.meshcat.PublishRecording()
        context = self.simulator.get_context()
        logs = self.handover.logs(read_logs(self.diagram.loggers, context))
        watching = self.X_WG is None
        h = logs.params[:, -1] if logs.params.shape[1] else (None, None)
        return read_result(
            self.diagram, context, self.scenario, self.obj, self.start_grasp,
            message=self.message,
            h_catch=None if watching else float(h[0]),
            h_down=None if watching else float(h[1]),
            wall_s=wall_s, build_s=self.build_s, logs=logs)

    def run(self, at_release=None) -> EpisodeResult:
        """Every stage in turn; `at_release` as run_episode's."""
        self.start()
        if self.running:
            if at_release is not None:
                try:
                    release = self.advance_to_release()
                    planned = at_release(release.object_state, release.t)
                except Exception:
                    self.stop_recording()
                    raise
                if planned is not None:
                    X_WG, parameters = planned
                    self.set_task(X_WG=X_WG, catch_parameters=parameters)
            self.advance_to_outcome()
        return self.result()


def run_episode(scenario: Scenario, obj: ObjectSpec, *, ik: ArmIk,
                X_WG: RigidTransform | None, catch_parameters=None,
                mlp_features=None, meshcat=None,
                throw_number: int = 1, at_release=None,
                throws: ThrowCache | None = None) -> EpisodeResult:
    """Throws `obj` and, unless X_WG is None (a watching throw), catches it:
    an `Episode` run through its stages. Arguments as Episode's.

    at_release: plans the catch while the object flies. Called once, at the
    release time (before the state machine reads the grasp pose), with the
    object's state then (13: quaternion wxyz, p_WO, w_WO, v_WO) and the
    time; it returns the grasp pose X_WG and the catch parameters (h_catch,
    h_down) that replace the ones given, None (the ones given stay: nothing
    in the episode changes), or raises InputError (no catch planned: the
    episode ends there and the error propagates). Requires catch_parameters
    and an X_WG (any: it is replaced)."""
    return Episode(scenario, obj, ik=ik, X_WG=X_WG,
                   catch_parameters=catch_parameters,
                   mlp_features=mlp_features, meshcat=meshcat,
                   throw_number=throw_number, throws=throws
                   ).run(at_release)
