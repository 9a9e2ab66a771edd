"""The CAN station: the PiPER over CAN behind the sim station's port contract.

`MakeCanStation` connects to the arm (or starts an emulator on a virtual bus and connects to
that), runs the start-up sequence and returns a Diagram whose ports are exactly those of
`ports`. Connecting is a side effect of building, like opening a device: call
`close_station(station)` when done (it stops streaming; the arm stays enabled and holds).
"""

from __future__ import annotations

import atexit

import can
from pydrake.systems.framework import Diagram, DiagramBuilder

from physcap_drake.can.emulator import PiperEmulator
from physcap_drake.can.faults import FaultSettings, FaultyBus
from physcap_drake.can.link import PiperLink
from physcap_drake.can.simulated_motion import SimulatedMotion, simulated_motion
from physcap_drake.station import ports
from physcap_drake.station.can_cameras import CanCameras, emulated_world, rendered_names
from physcap_drake.station.can_config import PiperCan
from physcap_drake.station.can_interface import PiperCanInterface
from physcap_drake.station.can_scene import EmulatedScene, NoScene

INTERFACE, SCENE = "piper_can", "scene"
EMULATED_FIRMWARE = "S-V1.8-2"


def _open_bus(config: PiperCan) -> can.BusABC:
    try:
        if config.interface in ("slcan", "gs_usb"):
            return can.Bus(interface=config.interface, channel=config.channel,
                           bitrate=1_000_000)
        return can.Bus(interface=config.interface, channel=config.channel)
    except (OSError, can.CanError, ValueError) as error:
        raise ConnectionError(f"station.interface {config.interface!r}, station.channel "
                              f"{config.channel!r}: cannot open the CAN bus: {error}") from None


def _start_emulator(scenario, config: PiperCan) -> tuple[PiperEmulator, SimulatedMotion]:
    """An emulator backed by `config.emulated` in the scenario's scene, running."""
    motion = simulated_motion(scenario)
    bus = can.Bus(interface="virtual", channel=config.channel)
    emulator = PiperEmulator(bus, firmware=config.firmware or EMULATED_FIRMWARE,
                             motion=motion, rate=200.0)
    return emulator.start(), motion


def MakeCanStation(scenario, meshcat=None) -> Diagram:
    """Builds the CAN station for `scenario` (whose `station` is a `PiperCan`); see module
    docstring. Raises ConnectionError / StartupError naming the bus and what failed."""
    config: PiperCan = scenario.station
    if meshcat is not None:
        raise ValueError("station: !PiperCan does not draw in Meshcat yet; run without "
                         "--meshcat")
    emulator = motion = None
    if config.emulate:
        emulator, motion = _start_emulator(emulated_world(scenario), config)
        faults = config.faults
        bus = FaultyBus(can.Bus(interface="virtual", channel=config.channel),
                        FaultSettings(faults.loss, faults.delay, faults.garble),
                        seed=faults.seed)
    else:
        bus = _open_bus(config)
    cameras = None
    try:
        if emulator is not None:
            scene = EmulatedScene(emulator, motion, rendered_names(scenario))
        else:
            scene = NoScene(0, 0, names=(ports.BODY_POSES,), why="this PiperCan station has "
                            "no simulated world (station.emulate: false)")
        cameras = CanCameras(scenario, scene, world=emulator is not None)
        link = PiperLink(bus, config).start()
    except BaseException:
        if cameras is not None:
            cameras.close()
        if emulator is not None:
            _release_emulator(emulator)
        raise
    builder = DiagramBuilder()
    interface = builder.AddNamedSystem(INTERFACE, PiperCanInterface(link, config))
    for name in ports.VECTOR_INPUTS:
        builder.ExportInput(interface.GetInputPort(name), name)
    for name in ports.VECTOR_OUTPUTS:
        builder.ExportOutput(interface.GetOutputPort(name), name)
    cameras.add_to(builder)
    diagram = builder.Build()
    diagram.set_name("station")
    # Threads must not outlive the interpreter (an emulator inside Drake's C++ would abort).
    atexit.register(_release, link, emulator)
    return diagram


def _release(link: PiperLink, emulator: PiperEmulator | None) -> None:
    link.close()
    if emulator is not None:
        _release_emulator(emulator)


def _release_emulator(emulator: PiperEmulator) -> None:
    emulator.stop()
    emulator.bus.shutdown()


def close_can_station(station: Diagram) -> None:
    """Stops streaming and closes the bus (the arm holds), then stops an emulator."""
    scene = station.GetSubsystemByName(SCENE)
    _release(station.GetSubsystemByName(INTERFACE).link,
             scene.emulator if isinstance(scene, EmulatedScene) else None)
