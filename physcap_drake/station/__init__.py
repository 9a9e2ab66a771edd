"""The PiPER station: one port contract (see `ports`), a simulated or a real arm behind it."""

from __future__ import annotations

from pydrake.geometry import Meshcat
from pydrake.systems.framework import Diagram

from physcap_drake.station.can_config import PiperCan
from physcap_drake.station.sim_config import SimPiper


def MakeStation(scenario, meshcat: Meshcat | None = None) -> Diagram:
    """Builds the station the scenario's `station:` names, with the ports of `ports`.

    Args:
        scenario: a loaded `physcap_drake.scenario.Scenario`.
        meshcat: when given, the scene is drawn there (per `scenario.visualization`).
    Returns:
        A Diagram with inputs piper.position, gripper.position, gripper.force_limit and the
        outputs listed in `physcap_drake.station.ports`.
    """
    station = scenario.station
    if isinstance(station, SimPiper):
        from physcap_drake.station.sim_station import MakeSimStation

        return MakeSimStation(scenario, meshcat)
    if isinstance(station, PiperCan):
        raise NotImplementedError(
            "station: !PiperCan (the real arm over CAN) is accepted by the scenario schema, "
            "but its hardware interface is not part of this release yet; use station: "
            "!SimPiper")
    raise TypeError(f"unknown station type {type(station).__name__}")
