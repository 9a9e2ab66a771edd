"""What `physcap arm park` and `physcap arm gripper` do with an open PiperLink.

Parking plans a collision-checked joint move (against the scenario's robot and fixed
environment) from where the arm is to the rest pose (skills.home_position),
streams it at PARK_SPEED_PERCENT of the arm's speed at most, waits until the arm is there,
then switches the motors off. Enabling asks first on a real arm (`can_gate`).
"""

from __future__ import annotations

import time

import numpy as np
from pydrake.trajectories import Trajectory

from physcap_drake.can import codec
from physcap_drake.control.errors import SkillRefused
from physcap_drake.control.planning_model import PlanningModel
from physcap_drake.control.trajectories import time_parameterize
from physcap_drake.station.can_config import MAX_JOINT_SPEED, rig_skills
from physcap_drake.station.can_gate import confirm_enabling
from physcap_drake.station.robot_model import robot_model

#: Parking moves at this share of the arm's speed at most, %.
PARK_SPEED_PERCENT = 20
#: The arm is parked once every joint is this close to the rest pose, rad (0.5°).
PARK_TOLERANCE = np.radians(0.5)
#: How long beyond the planned duration the arm may take to arrive, s.
PARK_MARGIN = 5.0
#: The way to rest is checked every this much joint travel, rad; a contact may deepen by
#: this much on it (numerical noise), m.
CHECK_STEP, CONTACT_SLACK = 0.01, 5e-4
#: Interval between the samples of the plan handed to the link, s.
SAMPLE_PERIOD = 0.01
#: The gripper is where it was sent once within this, m; it gets this long, s.
GRIPPER_TOLERANCE, GRIPPER_TIMEOUT = 0.002, 5.0
#: Effort limit of `arm gripper close`, N·m.
CLOSE_EFFORT = 1.0


def rest_pose(scenario) -> np.ndarray:
    return np.asarray(scenario.skills.home_position, dtype=float)


def park_plan(scenario, q: np.ndarray, opening: float) -> Trajectory:
    """The trajectory from `q` (rad) to the rest pose along a straight joint path at the
    parking speed, checked against the robot's model and fixed environment: no contact may
    deepen on the way (an arm left touching itself, as one that sank after an e-stop, may
    leave that contact). SkillRefused naming the bodies if the way is not clear."""
    station = scenario.station
    model = PlanningModel(robot=robot_model(scenario.directives, station.arm_model,
                                            station.gripper_model))
    skills = rig_skills(scenario.skills, station)
    rest = rest_pose(scenario)
    bad = [f"J{j + 1}" for j in range(6)
           if not model.lower[j] - 1e-9 <= rest[j] <= model.upper[j] + 1e-9]
    if bad:
        raise SkillRefused(f"park refused: skills.home_position is beyond the limits of "
                           f"{', '.join(bad)}")
    travel = float(np.abs(rest - q).max())
    allowed = 0.0
    for s in np.linspace(0.0, 1.0, max(int(np.ceil(travel / CHECK_STEP)), 1) + 1):
        contact = model.deepest_contact(q + s * (rest - q), opening)
        if s == 0.0 and contact is not None:
            allowed = contact[0]  # where it starts, touching
        elif contact is not None and contact[0] < allowed - CONTACT_SLACK:
            raise SkillRefused(f"park refused: the way to the rest pose would bring "
                               f"{contact[1]} into contact: move the arm clear by hand "
                               "(motors off) or with a skill, then park")
        else:
            allowed = 0.0 if contact is None else max(allowed, contact[0])
    return time_parameterize(np.column_stack([q, rest]), max_velocity=min(
        skills.max_joint_velocity, MAX_JOINT_SPEED * PARK_SPEED_PERCENT / 100.0),
        max_acceleration=skills.max_joint_acceleration)


def park(link, scenario, say=print) -> np.ndarray:
    """Parks the arm (module docstring); returns where it ended (rad). StartupError or
    SkillRefused (nothing moved) or TimeoutError (motors left on, holding) if it cannot."""
    link.connect()
    link.limit_speed(PARK_SPEED_PERCENT)
    feedback = link.listener.snapshot()
    plan = park_plan(scenario, feedback.q, feedback.gripper_opening)
    if not feedback.enabled.all():
        confirm_enabling(scenario.station)
    link.enable_motors().start_streaming()
    duration = plan.end_time() - plan.start_time()
    say(f"parking: {duration:.1f} s to the rest pose at {link.speed_percent} % speed")
    started = time.monotonic()
    while (t := time.monotonic() - started) < duration:
        q = plan.value(t).ravel()
        velocity = plan.EvalDerivative(t, 1).ravel()
        link.command(q, feedback.gripper_opening, 0.0, velocity)
        time.sleep(SAMPLE_PERIOD)
    rest = rest_pose(scenario)
    link.command(rest, feedback.gripper_opening, 0.0)
    deadline = time.monotonic() + PARK_MARGIN
    while np.abs(link.listener.snapshot().q - rest).max() > PARK_TOLERANCE:
        if time.monotonic() > deadline:
            link.stop_streaming()
            off = np.degrees(np.abs(link.listener.snapshot().q - rest).max())
            raise TimeoutError(f"the arm did not reach the rest pose ({off:.1f}° off after "
                               f"{duration + PARK_MARGIN:.0f} s): the motors stay on, "
                               "holding; look at the arm, then `physcap arm park` again")
        time.sleep(SAMPLE_PERIOD)
    link.stop_streaming()
    link.disable()
    return link.listener.snapshot().q


def move_gripper(link, station, opening: float, effort: float) -> float:
    """Opens or closes the gripper to `opening` (m) with `effort` (N·m); returns where it
    stopped (m): at the target, or blocked by what it holds."""
    link.connect()
    confirm_enabling(station)
    deadline = time.monotonic() + GRIPPER_TIMEOUT
    last, still = np.nan, 0
    while time.monotonic() < deadline:
        link.send_gripper(opening, effort)
        time.sleep(SAMPLE_PERIOD * 2)
        now = link.listener.snapshot().gripper_opening
        if abs(now - opening) <= GRIPPER_TOLERANCE:
            break
        still = still + 1 if abs(now - last) < 1e-5 else 0
        if still > 25:  # stopped short of the target half a second: blocked
            break
        last = now
    return link.listener.snapshot().gripper_opening


def zero_gripper(link) -> float:
    """Makes the gripper's current opening its zero (0x159 set-zero, the gripper disabled,
    as the vendor does); returns the opening it reports afterwards (m)."""
    link.connect()
    for _ in range(3):
        link.send_gripper(0.0, 0.0, codec.GRIPPER_DISABLE, set_zero=True)
        time.sleep(SAMPLE_PERIOD * 2)
    time.sleep(0.1)
    return link.listener.snapshot().gripper_opening
