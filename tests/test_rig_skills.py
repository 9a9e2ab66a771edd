"""The skills' limits a station imposes (`rig_skills`): tracking on any CAN station, speed on
a real arm."""

from __future__ import annotations

import dataclasses as dc

from physcap_drake.control.skills_config import SkillsConfig
from physcap_drake.station.can_config import PiperCan, rig_skills
from physcap_drake.station.sim_config import SimPiper


def test_a_simulated_station_keeps_the_scenarios_skills():
    skills = SkillsConfig()
    assert rig_skills(skills, SimPiper()) is skills


def test_a_can_station_judges_tracking_within_at_least_0_1_rad_and_0_3_s():
    emulated = PiperCan(interface="virtual", emulate=True)
    tight = dc.replace(SkillsConfig(), tracking_tolerance=0.02, tracking_delay=0.03)
    widened = rig_skills(tight, emulated)
    assert (widened.tracking_tolerance, widened.tracking_delay) == (0.1, 0.3)
    assert widened.max_joint_velocity == tight.max_joint_velocity  # emulated: not slowed
    wide = dc.replace(SkillsConfig(), tracking_tolerance=0.2, tracking_delay=0.5)
    kept = rig_skills(wide, emulated)
    assert (kept.tracking_tolerance, kept.tracking_delay) == (0.2, 0.5)


def test_a_real_arm_moves_at_most_at_its_rig_speed():
    real = PiperCan()  # socketcan, not emulated: 30 % of 3 rad/s, at most 1 rad/s, 2 rad/s²
    fast = dc.replace(SkillsConfig(), max_joint_velocity=3.0, max_joint_acceleration=5.0)
    slowed = rig_skills(fast, real)
    assert abs(slowed.max_joint_velocity - 0.9) < 1e-9
    assert slowed.max_joint_acceleration == 2.0
    assert (slowed.tracking_tolerance, slowed.tracking_delay) == (0.1, 0.3)
