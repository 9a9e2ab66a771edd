"""The CAN station: the PiPER over CAN behind the sim station's port contract.

`MakeCanStation` builds a Diagram whose ports are exactly those of `ports`: the
PiperCanInterface (commands and feedback) and, beside it, the scene system (the emulated
world's camera and ground truth, or NoScene; a camera driver goes here). Building connects
to nothing (it starts the station's processes, see `can_session`): the arm is connected,
enabled and streamed to when the simulator initializes the diagram (the interface's
initialization event), or earlier with `start_can_station`.
`close_can_station` stops streaming (the arm stays enabled and holds) and the emulator.
"""

from __future__ import annotations

from contextlib import contextmanager

from pydrake.systems.framework import Diagram, DiagramBuilder

from physcap_drake.station import ports
from physcap_drake.station.can_config import PiperCan
from physcap_drake.station.can_interface import PiperCanInterface
from physcap_drake.station.can_scene import SCENE_OUTPUTS, EmulatedScene, NoScene
from physcap_drake.station.can_session import CanSession

INTERFACE, SCENE = "piper_can", "scene"


def MakeCanStation(scenario, meshcat=None) -> Diagram:
    """Builds the CAN station for `scenario` (whose `station` is a `PiperCan`); see module
    docstring. Nothing is connected yet."""
    config: PiperCan = scenario.station
    if meshcat is not None:
        raise ValueError("station: !PiperCan does not draw in Meshcat yet; run without "
                         "--meshcat")
    session = CanSession(scenario)
    if config.emulate:
        scene = EmulatedScene(scenario, session)
        session.world_size = scene.world_size
    else:
        camera = next(c for c in scenario.cameras if c.name == "camera")
        scene = NoScene(camera.width, camera.height)
    session.wait_ready()  # the processes run, unconnected: initializing only connects
    builder = DiagramBuilder()
    interface = builder.AddNamedSystem(INTERFACE, PiperCanInterface(session, config))
    for name in ports.VECTOR_INPUTS:
        builder.ExportInput(interface.GetInputPort(name), name)
    for name in ports.VECTOR_OUTPUTS:
        builder.ExportOutput(interface.GetOutputPort(name), name)
    builder.AddNamedSystem(SCENE, scene)
    for name in SCENE_OUTPUTS:
        builder.ExportOutput(scene.GetOutputPort(name), name)
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
