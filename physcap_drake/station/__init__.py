"""The PiPER station: one port contract (see `ports`), a simulated or a real arm behind it."""

from __future__ import annotations

from contextlib import contextmanager

from pydrake.geometry import Meshcat
from pydrake.systems.framework import Context, Diagram

from physcap_drake.station.can_config import PiperCan
from physcap_drake.station.sim_config import SimPiper


def MakeStation(scenario, meshcat: Meshcat | None = None) -> Diagram:
    """Builds the station the scenario's `station:` names, with the ports of `ports`.

    Args:
        scenario: a loaded `physcap_drake.scenario.Scenario`.
        meshcat: when given, the scene is drawn there (per `scenario.visualization`).
    Returns:
        A Diagram with inputs piper.position, gripper.position, gripper.force_limit and the
        outputs listed in `physcap_drake.station.ports`. A PiperCan station connects when
        its simulator initializes (or `can_station.start_can_station`): release it with
        `close_station`.
    """
    station = scenario.station
    if isinstance(station, SimPiper):
        from physcap_drake.station.sim_station import MakeSimStation

        return MakeSimStation(scenario, meshcat)
    if isinstance(station, PiperCan):
        from physcap_drake.station.can_station import MakeCanStation

        return MakeCanStation(scenario, meshcat)
    raise TypeError(f"unknown station type {type(station).__name__}")


def close_station(station: Diagram) -> None:
    """Releases what a station holds outside Drake (camera devices and their recordings, a
    CAN link, an emulator thread); the real arm is left enabled and holding. Safe to call
    twice."""
    from physcap_drake.station.cameras import close_cameras
    from physcap_drake.station.can_station import INTERFACE, close_can_station

    close_cameras(station)
    if station.HasSubsystemNamed(INTERFACE):
        close_can_station(station)


def scene_plant(station: Diagram):
    """The plant of the simulated world behind `station`: the sim station's, or an emulated
    CAN station's copy of its emulated world. Raises RuntimeError for the real arm."""
    from physcap_drake.station.can_scene import SCENE, EmulatedScene

    if station.HasSubsystemNamed("plant"):
        return station.GetSubsystemByName("plant")
    scene = station.GetSubsystemByName(SCENE) if station.HasSubsystemNamed(SCENE) else None
    if not isinstance(scene, EmulatedScene):
        raise RuntimeError(NO_WORLD)
    return scene.plant


NO_WORLD = ("this station has no simulated world (the real arm over CAN): ground truth "
            "such as body poses does not exist")


@contextmanager
def station_at_rest(scenario):
    """Yields (station, its default context) for `scenario`: the world exactly as the scenario
    lays it out (objects at their default poses, the arm at `initial_arm_position`), to render
    or read from, never simulated and never written to; the station is closed on exit. A
    calibration view is one such station, with the board or the arm placed in the scenario."""
    station = MakeStation(scenario)
    try:
        yield station, station.CreateDefaultContext()
    finally:
        close_station(station)


def scene_snapshot(station: Diagram, root_context: Context):
    """(plant, plant context) of the simulated world now, to read: the sim station's live
    context (its time stands still between calls), or a copy of the emulated world's (the
    emulated arm moves on). Raises RuntimeError for the real arm."""
    from physcap_drake.station.can_scene import SCENE

    plant = scene_plant(station)
    if station.HasSubsystemNamed("plant"):
        return plant, plant.GetMyContextFromRoot(root_context)
    return plant, station.GetSubsystemByName(SCENE).snapshot()
