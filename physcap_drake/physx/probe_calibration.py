"""A rig's probe calibration file: what `physcap calibrate mass|stiffness --scenario RIG`
fitted on the real arm, named by the scenario's `physx.calibration_file`."""

# No `from __future__ import annotations`: yaml_load_typed reads the field types at run time.
import dataclasses as dc
from pathlib import Path

from pydrake.common.yaml import yaml_dump_typed, yaml_load_typed

from physcap_drake.physx.physx_config import PhysxConfig


@dc.dataclass
class ProbeCalibration:
    """The probes' values fitted on one arm; each replaces the scenario's own when loaded."""

    # Gain of each arm joint's torque reading, J1..J6 (MassProbeConfig.torque_gain), fitted
    # by weighing a weight of known mass; empty: not fitted.
    torque_gain: list[float] = dc.field(default_factory=list)
    # The gripper's own deformation on a rigid block, mm, subtracted from every squeeze
    # (StiffnessProbeConfig.gripper_offset_mm); negative: not measured.
    gripper_offset_mm: float = -1.0
    # How each value was fitted (command, weight or block, date).
    torque_gain_source: str = ""
    gripper_offset_source: str = ""


def load_probe_calibration(path: str | Path) -> ProbeCalibration:
    """Reads a probe calibration file; raises FileNotFoundError naming it."""
    if not Path(path).is_file():
        raise FileNotFoundError(f"probe calibration file {path} does not exist")
    return yaml_load_typed(schema=ProbeCalibration, filename=str(path))


def save_probe_calibration(calibration: ProbeCalibration, path: str | Path) -> None:
    """Writes `calibration` (creating the folder) and reads it back."""
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    Path(path).write_text("# Fitted on the arm by `physcap calibrate mass|stiffness "
                          "--scenario`; see docs/rig_calibration.md.\n"
                          + yaml_dump_typed(calibration))
    load_probe_calibration(path)


def apply_probe_calibration(physx: PhysxConfig, calibration: ProbeCalibration) -> None:
    """Puts the fitted values of `calibration` into the probes' configuration."""
    if calibration.torque_gain:
        physx.mass.torque_gain = list(calibration.torque_gain)
    if calibration.gripper_offset_mm >= 0.0:
        physx.stiffness.gripper_offset_mm = calibration.gripper_offset_mm
