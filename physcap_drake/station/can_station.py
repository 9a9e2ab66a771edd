"""The CAN station: the PiPER over CAN behind the sim station's port contract.

Design notes: docs/design/station.md.
"""

from __future__ import annotations

from contextlib import contextmanager

from pydrake.systems.framework import Diagram, DiagramBuilder

from physcap_drake.station import ports
from physcap_drake.station.can_cameras import CanCameras, emulated_world, rendered_names
from physcap_drake.station.can_config import PiperCan
from physcap_drake.station.can_interface import PiperCanInterface
from physcap_drake.station.can_scene import EmulatedScene, NoScene
from physcap_drake.station.can_session import CanSession
from physcap_drake.station.can_view import add_measured_view

INTERFACE = "piper_can"


def MakeCanStation(scenario, meshcat=None) -> Diagram:
    """Builds the CAN station for `scenario` (whose `station` is a `PiperCan`); see the design
    notes. Nothing is connected yet. With `meshcat`, the robot is drawn there at its
    measured joints (`can_view`)."""
    config: PiperCan = scenario.station
    # The emulated arm's process simulates the world (its cameras are built, never
    # rendered): this station renders them from its own copy of that world (EmulatedScene).
    session = CanSession(emulated_world(scenario))
    cameras = None
    try:
        if config.emulate:
            scene = EmulatedScene(emulated_world(scenario), session, rendered_names(scenario))
            session.world_size = scene.world_size
        else:
            scene = NoScene(0, 0, names=(ports.BODY_POSES,), why="this PiperCan station has "
                            "no simulated world (station.emulate: false)")
        cameras = CanCameras(scenario, scene, world=config.emulate)
        session.wait_ready()  # the processes run, unconnected: initializing only connects
    except BaseException:
        if cameras is not None:
            cameras.close()
        session.close()
        raise
    builder = DiagramBuilder()
    interface = builder.AddNamedSystem(INTERFACE, PiperCanInterface(session, config))
    for name in ports.VECTOR_INPUTS:
        builder.ExportInput(interface.GetInputPort(name), name)
    for name in (*ports.VECTOR_OUTPUTS, ports.ARM_FAULT):
        builder.ExportOutput(interface.GetOutputPort(name), name)
    cameras.add_to(builder)
    if meshcat is not None:
        add_measured_view(builder, interface, scenario, meshcat)
    diagram = builder.Build()
    diagram.set_name("station")
    return diagram


def can_session(station: Diagram) -> CanSession:
    return station.GetSubsystemByName(INTERFACE).session


def start_can_station(station: Diagram) -> None:
    """Connects the station now (emulator, streaming process, the arm's start-up) instead
    of at its simulator's initialization. Raises ConnectionError / StartupError naming the
    bus and what failed."""
    can_session(station).start()


def close_can_station(station: Diagram) -> None:
    """Stops streaming (the arm holds), then the emulator. Safe to call twice."""
    can_session(station).close()


@contextmanager
def running_can_station(station: Diagram):
    """Connected inside the block, released (the arm holding) after it, whatever happens."""
    start_can_station(station)
    try:
        yield station
    finally:
        close_can_station(station)
