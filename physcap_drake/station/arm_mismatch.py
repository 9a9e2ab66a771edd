"""An arm that is not its model: deviations of a simulated PiPER drawn from a seed, for
`physcap calibrate --mismatch` and for an emulated twin's `station.emulated_mismatch`.

Design notes: docs/design/app.md.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from physcap_drake.station.sim_config import LinkDeviation, SimPiper

GROUPS = ("links", "torque_gain", "torque_offset", "friction", "fingers", "moduli")
ARM_LINKS = tuple(f"link{i}" for i in range(1, 7))
MASS_SCALE = COM_SCALE = (0.8, 1.2)
TORQUE_GAIN = (0.95, 1.05)
TORQUE_OFFSET = np.array([0.05, 0.05, 0.05, 0.01, 0.01, 0.01])  # N·m, ±
COULOMB = np.array([0.03, 0.03, 0.03, 0.01, 0.01, 0.01])  # N·m, upper bound
VISCOUS = 0.05  # N·m·s/rad, upper bound
FINGER_COMPLIANCE = 2e-5  # m/N, upper bound
MODULUS_SCALE = (0.85, 1.15)


def parse_groups(text: str) -> tuple[str, ...]:
    """"all" or a comma-separated list of GROUPS."""
    if text.strip() == "all":
        return GROUPS
    names = tuple(name.strip() for name in text.split(",") if name.strip())
    unknown = [name for name in names if name not in GROUPS]
    if unknown or not names:
        raise ValueError(f"unknown mismatch group(s) {', '.join(map(repr, unknown)) or '(none)'}"
                         f"; use 'all' or a comma-separated list of: {', '.join(GROUPS)}")
    return names


def _rng(seed: int, group: str) -> np.random.Generator:
    return np.random.default_rng((seed, 4242, GROUPS.index(group)))


def draw(seed: int, groups: tuple[str, ...]) -> dict[str, Any]:
    """The deviations of trial `seed` for `groups`, as plain data (for the report)."""
    drawn: dict[str, Any] = {}
    if "links" in groups:
        rng = _rng(seed, "links")
        drawn["links"] = {name: {"mass_scale": float(rng.uniform(*MASS_SCALE)),
                                 "com_scale": rng.uniform(*COM_SCALE, 3).tolist()}
                          for name in ARM_LINKS}
    if "torque_gain" in groups:
        drawn["torque_gain"] = _rng(seed, "torque_gain").uniform(*TORQUE_GAIN, 6).tolist()
    if "torque_offset" in groups:
        rng = _rng(seed, "torque_offset")
        drawn["torque_offset"] = (TORQUE_OFFSET * rng.uniform(-1.0, 1.0, 6)).tolist()
    if "friction" in groups:
        rng = _rng(seed, "friction")
        drawn["joint_friction"] = (COULOMB * rng.uniform(0.0, 1.0, 6)).tolist()
        drawn["joint_damping"] = rng.uniform(0.0, VISCOUS, 6).tolist()
    if "fingers" in groups:
        drawn["finger_compliance"] = float(_rng(seed, "fingers").uniform(0.0,
                                                                         FINGER_COMPLIANCE))
    if "moduli" in groups:
        drawn["modulus_scale"] = float(_rng(seed, "moduli").uniform(*MODULUS_SCALE))
    return drawn


def apply(station: SimPiper, drawn: dict[str, Any], specimen: str | None = None) -> None:
    """Puts drawn deviations into a simulated station (`as_built` and the torque sensor's
    gain and offset; each value set, not scaled, so applying twice changes nothing); the
    modulus scale goes to the compliant model `specimen` (None: to no model)."""
    as_built = station.as_built
    if "links" in drawn:
        as_built.links = {name: LinkDeviation(**values)
                          for name, values in drawn["links"].items()}
    if "torque_gain" in drawn:
        station.torque_noise.gain = list(drawn["torque_gain"])
    if "torque_offset" in drawn:
        station.torque_noise.offset = list(drawn["torque_offset"])
    if "joint_friction" in drawn:
        as_built.joint_friction = list(drawn["joint_friction"])
        as_built.joint_damping = list(drawn["joint_damping"])
    if "finger_compliance" in drawn:
        as_built.finger_compliance = drawn["finger_compliance"]
    if "modulus_scale" in drawn and specimen is not None:
        as_built.modulus_scale = {specimen: drawn["modulus_scale"]}
