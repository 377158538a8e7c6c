"""The scenario's bounds (`validate`): each field of the project's range,
and of `plant_config` what the station relies on (the time step's range,
point contact, an approximation that converges on throw impacts); and for
every field of the project, whatever its section: every number finite;
every arm joint angle (a list of 6 named `*_q_rad`, or a list of such
lists) within the PUMA 560's joint limits read from sdf/puma560.sdf
(`arm_joint_limits`); the throw's knot times increasing from 0, at most
10 s. An InputError names the field, its value and what was expected."""

import dataclasses as dc
import math
import re

from pydrake.multibody.parsing import ModelDirective
from pydrake.systems.analysis import GetIntegrationSchemes, SimulatorConfig

from regrasp_drake.errors import field_error
from regrasp_drake.parameter_space import H_CATCH_RANGE, H_DOWN_RANGE
from regrasp_drake.planning.grasp import OFFSET_LIMIT_MM, TARGET_KINDS
from regrasp_drake.world.robot import (
    ARM_MODEL_NAME,
    CLOSING_ORDERS,
    HAND_MODEL_NAME,
    arm_joint_limits,
)

_APPROXIMATIONS = ("sap", "similar", "lagged")
_THROWS = ("fingers", "palm_toss")
_PALMS = ("box", "pads")
_OBJECT_BOXES = ("exact", "rounded")
_SOURCES = ("fixed", "mlp")


def _in_range(field, value, lo, hi, unit=""):
    if not (isinstance(value, (int, float)) and math.isfinite(value)
            and lo <= value <= hi):
        raise field_error(field, value, f"a number in [{lo}, {hi}]{unit}")


def _check_generic(value, field: str = "") -> None:
    """The checks of every field (module docstring): finite numbers, arm
    joint angles within the PUMA's limits."""
    if dc.is_dataclass(value):
        for f in dc.fields(value):
            name = f"{field}.{f.name}" if field else f.name
            _check_generic(getattr(value, f.name), name)
    elif isinstance(value, float) and not math.isfinite(value):
        raise field_error(field, value, "a finite number")
    elif isinstance(value, list):
        for i, item in enumerate(value):
            _check_generic(item, f"{field}[{i}]")
        named = re.sub(r"(\[\d+\])+$", "", field)
        if named.endswith("_q_rad") and not any(isinstance(v, list) for v in value):
            if len(value) != 6:
                raise field_error(field, value, "6 joint angles")
            for i, (q, (lo, hi)) in enumerate(zip(value, arm_joint_limits())):
                _in_range(f"{field}[{i}]", q, lo, hi,
                          f" rad (joint{i + 1}'s limits in puma560.sdf)")


def validate(s):
    """Checks every field's range of the Scenario `s` (station/scenario.py,
    which imports this); returns `s` or raises InputError."""
    _check_generic(s)
    for check in (_check_plant, _check_contact_and_arm, _check_throw,
                  _check_sensors, _check_catch, _check_monitor_and_regrasp):
        check(s)
    return s


def _check_plant(s) -> None:
    """plant_config, simulator_config, catch_time_step_s,
    landing_time_step_s, landing_lead_s, directives."""
    dt = s.plant_config.time_step
    if dt != 0.0:
        _in_range("plant_config.time_step", dt, 1e-5, 5e-3,
                  " s, or 0 (a continuous plant)")
    _check_simulator_config(s.simulator_config, continuous=dt == 0.0)
    if s.catch_time_step_s is not None:
        if dt == 0.0:
            raise field_error("catch_time_step_s", s.catch_time_step_s,
                              "null with a continuous plant "
                              "(plant_config.time_step 0)")
        _in_range("catch_time_step_s", s.catch_time_step_s, dt, 5e-3,
                  f" s (at least plant_config.time_step = {dt} s)")
    if s.target_catch_time_step_s is not None and dt != 0.0:
        _in_range("target_catch_time_step_s", s.target_catch_time_step_s,
                  dt, 5e-3, f" s (at least plant_config.time_step = {dt} s)")
    if s.landing_time_step_s is not None and dt != 0.0:
        catch = min(s.catch_time_step_s or dt,
                    s.target_catch_time_step_s or dt)
        _in_range("landing_time_step_s", s.landing_time_step_s, 1e-5, catch,
                  f" s (at most the catch's step, {catch} s)")
    _in_range("landing_lead_s", s.landing_lead_s, 0.0, 2.0, " s")
    if s.landing_settle_s is not None:
        _in_range("landing_settle_s", s.landing_settle_s, 0.0, 4.0, " s")
    _check_directives(s.directives)
    if s.plant_config.contact_model != "point":
        raise field_error("plant_config.contact_model",
                          s.plant_config.contact_model, "'point'")
    if s.plant_config.discrete_contact_approximation not in _APPROXIMATIONS:
        raise field_error("plant_config.discrete_contact_approximation",
                          s.plant_config.discrete_contact_approximation,
                          f"one of {_APPROXIMATIONS}")
    _in_range("gravity_m_per_s2", s.gravity_m_per_s2, 0.0, 30.0, " m/s²")


def _check_contact_and_arm(s) -> None:
    c = s.contact
    for name, value, allowed in (("palm", c.palm, _PALMS),
                                 ("object_boxes", c.object_boxes,
                                  _OBJECT_BOXES)):
        if value not in allowed:
            raise field_error(f"contact.{name}", value, f"one of {allowed}")
    _in_range("contact.friction_coefficient", c.friction_coefficient, 0.0, 5.0)
    _in_range("contact.point_stiffness_N_per_m", c.point_stiffness_N_per_m,
              1.0, 1e8, " N/m")
    _in_range("contact.hunt_crossley_dissipation_s_per_m",
              c.hunt_crossley_dissipation_s_per_m, 0.0, 1e3, " s/m")
    for name in ("kp", "ki", "kd"):
        gains = getattr(s.arm, name)
        if len(gains) != 6:
            raise field_error(f"arm.{name}", gains, "6 gains, one per arm joint")
        for i, g in enumerate(gains):
            _in_range(f"arm.{name}[{i}]", g, 0.0, 1e6)


def _check_throw(s) -> None:
    t = s.throw
    if t.kind not in _THROWS:
        raise field_error("throw.kind", t.kind, f"one of {_THROWS}")
    _in_range("throw.settle_s", t.settle_s, 0.0, 5.0, " s")
    p = t.toss
    _in_range("throw.toss.launch_speed_m_per_s", p.launch_speed_m_per_s,
              0.5, 5.0, " m/s")
    _in_range("throw.toss.lift_s", p.lift_s, 0.05, 1.0, " s")
    _in_range("throw.toss.brake_deceleration_m_per_s2",
              p.brake_deceleration_m_per_s2,
              round(1.3 * s.gravity_m_per_s2, 4), 100.0,
              " m/s² (at least 1.3 g: the object must leave the palm)")
    _in_range("throw.toss.brake_ramp_s", p.brake_ramp_s, 0.005, 0.2, " s")
    _in_range("throw.toss.spin_rad_per_s", p.spin_rad_per_s, -15.0, 15.0,
              " rad/s")
    _in_range("throw.toss.spin_hold_s", p.spin_hold_s, 0.0, 0.2, " s")
    _in_range("throw.toss.spin_stop_s", p.spin_stop_s, 0.02, 1.0, " s")
    if len(t.knot_times_s) < 2 or len(t.knot_times_s) != len(t.knot_q_rad):
        raise field_error("throw.knot_times_s", t.knot_times_s,
                          "at least 2 times, one per entry of throw.knot_q_rad")
    if t.knot_times_s[0] != 0.0 or t.knot_times_s[-1] > 10.0 or not all(
            b > a for a, b in zip(t.knot_times_s, t.knot_times_s[1:])):
        raise field_error("throw.knot_times_s", t.knot_times_s,
                          "increasing times starting at 0, at most 10 s")
    for i, q in enumerate(t.knot_q_rad):
        if len(q) != 6:
            raise field_error(f"throw.knot_q_rad[{i}]", q, "6 joint angles")
    _in_range("throw.release_time_s", t.release_time_s, 0.0,
              t.knot_times_s[-1], " s")
    _in_range("throw.hold_closure", t.hold_closure, 0.0, 1.0)
    _in_range("throw.park_joint1_offset_rad", t.park_joint1_offset_rad,
              -math.pi, math.pi, " rad")
    _in_range("throw.noise.release_time_std_s", t.noise.release_time_std_s,
              0.0, 0.05, " s")
    _in_range("throw.noise.joint_velocity_std_rad_per_s",
              t.noise.joint_velocity_std_rad_per_s, 0.0, 1.0, " rad/s")
    if not isinstance(t.noise.seed, int) or t.noise.seed < 0:
        raise field_error("throw.noise.seed", t.noise.seed,
                          "an integer >= 0")


def _check_sensors(s) -> None:
    n, dt = s.sensors, s.plant_config.time_step
    _in_range("sensors.period_s", n.period_s, max(dt, 1e-4), 0.05, " s")
    for name, step in (("plant_config.time_step", dt),
                       ("catch_time_step_s", s.catch_time_step_s),
                       ("landing_time_step_s",
                        s.landing_time_step_s if dt else None)):
        ratio = n.period_s / step if step else 1.0
        if abs(ratio - round(ratio)) > 1e-9 * ratio:
            raise field_error("sensors.period_s", n.period_s,
                              f"a whole multiple of {name} = {step} s")
    _in_range("sensors.palm_range_m", n.palm_range_m, 0.01, 1.0, " m")
    _in_range("sensors.approach_range_m", n.approach_range_m, 0.40, 2.0, " m")
    _in_range("sensors.levels", n.levels, 2, 1e6)


def _check_catch(s) -> None:
    k, n = s.catch, s.sensors
    _in_range("catch.catch_height_m", k.catch_height_m, 0.2, 1.6, " m")
    _in_range("catch.tilt_tolerance", k.tilt_tolerance, 0.0, 1.0)
    _in_range("catch.height_band_m", k.height_band_m, 0.0, 1.0, " m")
    if k.palm_max_tilt_rad is not None:
        _in_range("catch.palm_max_tilt_rad", k.palm_max_tilt_rad, 0.0, 0.6,
                  " rad")
    _in_range("catch.palm_com_margin_m", k.palm_com_margin_m, 0.0, 0.05, " m")
    _in_range("catch.palm_toward_landing_end_m", k.palm_toward_landing_end_m,
              0.0, 0.03, " m")
    _in_range("catch.target_palm_toward_landing_end_m",
              k.target_palm_toward_landing_end_m, 0.0, 0.03, " m")
    _in_range("catch.palm_toward_fingers_m", k.palm_toward_fingers_m, 0.0,
              0.03, " m")
    _in_range("catch.palm_across_com_fraction", k.palm_across_com_fraction,
              0.0, 1.0)
    if len(k.ik_seed_q_rad) != 6:
        raise field_error("catch.ik_seed_q_rad", k.ik_seed_q_rad, "6 joint angles")
    _in_range("catch.move_to_grasp_s", k.move_to_grasp_s, 0.05, 3.0, " s")
    _in_range("catch.max_move_torque_fraction", k.max_move_torque_fraction,
              0.05, 1.0)
    _in_range("catch.grasp_tolerance_m", k.grasp_tolerance_m, 1e-5, 0.05, " m")
    _in_range("catch.preshape_closure", k.preshape_closure, 0.0, 0.8)
    if k.preshape_distal_closure is not None:
        _in_range("catch.preshape_distal_closure", k.preshape_distal_closure,
                  0.0, 0.8)
    if k.closing_order not in CLOSING_ORDERS:
        raise field_error("catch.closing_order", k.closing_order,
                          f"one of {list(CLOSING_ORDERS)}")
    _in_range("catch.lower_speed_m_per_s", k.lower_speed_m_per_s, 0.01, 5.0,
              " m/s")
    _in_range("catch.palm_stop_level", k.palm_stop_level, 0, n.levels)
    _in_range("catch.return_s", k.return_s, 0.05, 3.0, " s")
    if k.lower_ends_moving is True and not k.return_from_motion:
        raise field_error("catch.lower_ends_moving", k.lower_ends_moving,
                          "false unless catch.return_from_motion is true (the "
                          "return takes over from the lowering's motion)")
    for name in ("follow_ramp_s", "follow_hold_s", "follow_stop_s",
                 "follow_back_s"):
        _in_range(f"catch.{name}", getattr(k, name), 0.01, 1.0, " s")
    _in_range("catch.follow_max_torque_fraction",
              k.follow_max_torque_fraction, 0.05, 1.0)
    if k.parameter_source not in _SOURCES:
        raise field_error("catch.parameter_source", k.parameter_source,
                          f"one of {_SOURCES}")
    check_catch_parameters(k.h_catch_m, k.h_down_m,
                           names=("catch.h_catch_m", "catch.h_down_m"))


def _check_monitor_and_regrasp(s) -> None:
    m, n = s.monitor, s.sensors
    _in_range("monitor.palm_grasp_level", m.palm_grasp_level, 0, n.levels)
    _in_range("monitor.ir_window_s", m.ir_window_s, 0.0, 2.0, " s")
    _in_range("monitor.bumper_window_s", m.bumper_window_s, 0.0, 2.0, " s")
    _in_range("monitor.finger_stall_rad", m.finger_stall_rad, 0.0, 1.0,
              " rad")
    _in_range("monitor.finger_rest_rad_per_s", m.finger_rest_rad_per_s, 0.0,
              5.0, " rad/s")
    _in_range("monitor.finger_window_s", m.finger_window_s, 0.0, 2.0, " s")
    _in_range("monitor.hold_s", m.hold_s, 0.0, 5.0, " s")
    _in_range("monitor.below_palm_m", m.below_palm_m, 0.0, 1.0, " m")
    _in_range("monitor.ground_clearance_m", m.ground_clearance_m, 0.0, 1.0, " m")
    _in_range("monitor.max_time_s", m.max_time_s, 0.5, 60.0, " s")
    if s.regrasp.target not in TARGET_KINDS:
        raise field_error("regrasp.target", s.regrasp.target,
                          f"one of {TARGET_KINDS}")
    _in_range("regrasp.offset_mm", s.regrasp.offset_mm, -OFFSET_LIMIT_MM,
              OFFSET_LIMIT_MM, " mm")


def _check_directives(directives: list[ModelDirective]) -> None:
    """The robot's directives add the arm and the hand and weld the hand to
    one frame of the arm, where the arm-only plant of the controller and the
    inverse kinematics carries it (robot.make_arm_control_plant)."""
    models = [d.add_model.name for d in directives if d.add_model]
    if ARM_MODEL_NAME not in models or HAND_MODEL_NAME not in models:
        raise field_error("directives", models, f"add_model entries named "
                          f"{ARM_MODEL_NAME!r} and {HAND_MODEL_NAME!r}")
    mounts = [d.add_weld.parent for d in directives if d.add_weld
              and d.add_weld.child.startswith(f"{HAND_MODEL_NAME}::")]
    if len(mounts) != 1 or not mounts[0].startswith(f"{ARM_MODEL_NAME}::"):
        raise field_error(
            "directives", mounts, f"the hand welded (add_weld, child "
            f"{HAND_MODEL_NAME}::...) to one frame of the arm (parent "
            f"{ARM_MODEL_NAME}::...)")


def _check_simulator_config(c: SimulatorConfig, continuous: bool) -> None:
    """simulator_config's checks: a scheme Drake knows, and CENIC exactly
    when the plant is continuous (CENIC refuses a discrete plant; the
    station's continuous plant is built and tested for CENIC only)."""
    schemes = tuple(GetIntegrationSchemes())
    if c.integration_scheme not in schemes:
        raise field_error("simulator_config.integration_scheme",
                          c.integration_scheme, f"one of {schemes}")
    if continuous != (c.integration_scheme == "cenic"):
        raise field_error(
            "simulator_config.integration_scheme", c.integration_scheme,
            "'cenic' with plant_config.time_step 0 (a continuous plant), "
            "another scheme with a discrete plant")
    _in_range("simulator_config.accuracy", c.accuracy, 1e-12, 1.0)
    _in_range("simulator_config.max_step_size", c.max_step_size, 1e-6, 1.0,
              " s")
    if c.start_time != 0.0:
        raise field_error("simulator_config.start_time", c.start_time,
                          "0 (an episode starts at t = 0 s)")
    _in_range("simulator_config.target_realtime_rate",
              c.target_realtime_rate, 0.0, 1e3)


def check_catch_parameters(h_catch, h_down,
                           names=("h_catch_m", "h_down_m")):
    """Refuses (h_catch, h_down) outside the paper's parameter space, naming
    the offending one by `names`."""
    _in_range(names[0], h_catch, *H_CATCH_RANGE, " m")
    _in_range(names[1], h_down, *H_DOWN_RANGE, " m")


