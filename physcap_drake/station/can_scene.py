"""What the CAN station's camera and ground-truth ports show: the emulator's scene, or nothing.

Design notes: docs/design/station.md.
"""

from __future__ import annotations

import dataclasses as dc
from contextlib import contextmanager
from functools import partial

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.framework import Context, DiscreteValues, LeafSystem

from physcap_drake.station import ports
from physcap_drake.station.can_session import CanSession
from physcap_drake.station.ports import camera_port
from physcap_drake.weak_method import weak_method

#: The scene's name in a CAN station (the subsystem the emulated world's images come from).
SCENE = "scene"
SCENE_OUTPUTS = (*ports.IMAGE_OUTPUTS, ports.BODY_POSES)
#: The images a rendered camera gives, and the name of the station's camera.
IMAGES = ("rgb", "depth", "label")
MAIN_CAMERA = "camera"


class EmulatedScene(LeafSystem):
    """`<camera>.rgb`, `<camera>.depth`, `<camera>.label` of each rendered camera in
    `cameras` (names of the emulator's simulated station's cameras; the station camera by
    default) and body_poses, all of the emulator's simulated scene.

    Output ports:
        <camera>.rgb (ImageRgba8U), <camera>.depth (ImageDepth32F, m),
        <camera>.label (ImageLabel16I) of each camera in `cameras`.
        body_poses (list of RigidTransform): X_WB by body index, world frame.
    Discrete state: the emulated plant's positions and velocities (`world_size` values) as
    the emulated arm last published them, latched by this system's own events: at
    initialization and every period at which the emulated arm publishes its world (1 /
    `piper_emulator.emulator_process.FIRMWARE_RATE` s; more often would read nothing new), or,
    once the station was released, the world as it was then. The outputs read only that
    state: they set it into this system's private copy of the scene (a scratch context no
    other system sees) and evaluate the simulated station's port there, so rendering never
    holds up the arm. The values are the same types as the sim station's. Body poses are in
    the world frame, indexed by BodyIndex of `plant`; they and the label image are ground truth for
    success checks only.
    """

    def __init__(self, scenario, session: CanSession, cameras: tuple[str, ...] = (MAIN_CAMERA,)):
        super().__init__()
        from physcap_drake.station.sim_station import MakeSimStation

        self.session = session  # resources shared with the emulator, not state
        # The copy keeps the model files' masses: the hidden ones are the emulated world's.
        self.station = MakeSimStation(dc.replace(scenario, station=scenario.station.emulated,
                                                 body_masses={}))
        self.plant = self.station.GetSubsystemByName("plant")
        # The scene copy's scratch context, owned by this system (the usual Drake way to
        # evaluate a model outside the diagram); set from this system's state before use.
        self._context = self.station.CreateDefaultContext()
        self._plant_context = self.plant.GetMyMutableContextFromRoot(self._context)
        self._world = self.DeclareDiscreteState(
            self.plant.GetPositionsAndVelocities(self._plant_context))
        self.DeclareInitializationDiscreteUpdateEvent(self._latch)
        # Only an emulated scene imports the emulator (for the rate it publishes at).
        from physcap_drake.piper_emulator.emulator_process import FIRMWARE_RATE

        self.DeclarePeriodicDiscreteUpdateEvent(1.0 / FIRMWARE_RATE, 0.0, self._latch)
        names = [camera_port(camera, image) for camera in cameras for image in IMAGES]
        for name in (*names, ports.BODY_POSES):
            port = self.station.GetOutputPort(name)
            self.DeclareAbstractOutputPort(name, port.Allocate,
                                           partial(weak_method(self._copy), port),
                                           {self.discrete_state_ticket(self._world)})
        # The first image costs several times the next ones (renderer set-up): pay it now.
        for camera in cameras:
            self.station.GetOutputPort(camera_port(camera, "rgb")).Eval(self._context)

    @property
    def world_size(self) -> int:
        """The emulated plant's positions + velocities (what the emulator publishes)."""
        return self.plant.num_positions() + self.plant.num_velocities()

    @property
    def emulator(self):
        """The emulated arm's process handle (`piper_emulator.emulator_process.EmulatorProcess`)."""
        if self.session.emulator is None:
            raise RuntimeError("the CAN station is not started: initialize its simulator, "
                               "or call start_can_station(station)")
        return self.session.emulator

    def world_state(self, context: Context) -> np.ndarray:
        """The emulated plant's positions and velocities latched in this system's `context`."""
        return context.get_discrete_state(self._world).get_value()

    def _latch(self, context: Context, state: DiscreteValues) -> None:
        state.get_mutable_vector(self._world).SetFromVector(self._published())

    def _copy(self, port, context: Context, output: AbstractValue) -> None:
        """`output` := the scene copy's `port` with the world state latched in `context`."""
        self.plant.SetPositionsAndVelocities(self._plant_context, self.world_state(context))
        output.SetFrom(port.EvalAbstract(self._context))

    def _published(self) -> np.ndarray:
        """The world's state as the emulated arm publishes it now, or, once the station was
        released, as it was then."""
        if self.session.emulator is None and self.session.last_world is not None:
            world = self.session.last_world
        else:
            world = self.emulator.world()
        if world is None:
            raise RuntimeError("the emulated arm has not published its world yet")
        return world[1]

    def _sync(self) -> None:
        """Sets the world as published now into the scratch copy (for the readers outside
        the diagram below; the outputs read this system's state instead)."""
        self.plant.SetPositionsAndVelocities(self._plant_context, self._published())

    def snapshot(self) -> Context:
        """The plant's context as the emulated world is now (a copy, to read)."""
        self._sync()
        return self.plant.GetMyContextFromRoot(self._context.Clone())

    @contextmanager
    def ground_truth(self):
        """Yields (plant, plant context) of the world now; the positions and velocities the
        block changes are written to the emulated world when the block ends (as an operator
        moves things). Raises RuntimeError if the block changed a parameter (a mass): the
        emulated world's parameters are its model's (the scenario's body_masses)."""
        self._sync()
        context = self._plant_context
        before = _parameters(context)
        state = self.plant.GetPositionsAndVelocities(context).copy()
        try:
            yield self.plant, context
            changed = [i for i, v in _parameters(context).items()
                       if not np.array_equal(v, before[i], equal_nan=True)]
            if changed:
                raise RuntimeError(
                    f"the emulated world's parameters (groups {changed}) cannot change while "
                    "it runs: give its hidden masses in the scenario's body_masses, which the "
                    "emulated arm's world is built with")
            now = self.plant.GetPositionsAndVelocities(context)
            if not np.array_equal(now, state):
                self.emulator.set_world(now.copy())
        finally:  # the scratch copy keeps the model's parameters
            for index, values in before.items():
                context.get_mutable_numeric_parameter(index).SetFromVector(values)


def _parameters(context: Context) -> dict[int, np.ndarray]:
    return {i: context.get_numeric_parameter(i).get_value().copy()
            for i in range(context.num_numeric_parameter_groups())}


class NoScene(LeafSystem):
    """Ports of a station without a simulation that keep the port contract but refuse to be
    evaluated, naming the port (see the design notes).

    Output ports (each raises RuntimeError naming itself and `why` when evaluated):
        camera.rgb, camera.depth, camera.label, body_poses: those of `names`.
    No state.

    Args:
        camera_width, camera_height: size of the images the refused camera ports allocate, px.
        names: which of SCENE_OUTPUTS to declare (all by default).
        why: what is missing, said after the port's name in the error.
    """

    def __init__(self, camera_width: int, camera_height: int, *,
                 names: tuple[str, ...] = SCENE_OUTPUTS,
                 why: str = "this PiperCan station has no emulator (station.emulate: false) "
                            "and no camera driver"):
        super().__init__()
        from pydrake.systems.sensors import ImageDepth32F, ImageLabel16I, ImageRgba8U

        empty = MultibodyPlant(0.0)
        empty.Finalize()
        models = {"rgb": ImageRgba8U(camera_width, camera_height),
                  "depth": ImageDepth32F(camera_width, camera_height),
                  "label": ImageLabel16I(camera_width, camera_height)}
        for name in names:
            if name == ports.BODY_POSES:
                allocate = empty.get_body_poses_output_port().Allocate
            else:
                allocate = _allocator(models[name.rsplit(".", 1)[1]])  # <camera>.<image>
            self.DeclareAbstractOutputPort(name, allocate, _refusal(name, why))


def _refusal(name: str, why: str):
    """The calculation of NoScene's port `name`: an error saying what it is and `why` it is
    missing (a function of its own: a closure over the system would keep it alive, see
    physcap_drake.weak_method)."""
    def calc(context: Context, output: AbstractValue) -> None:
        what = ("simulation-only ground truth" if name == ports.BODY_POSES
                or name.endswith(".label") else "a camera image")
        raise RuntimeError(f"{name} is {what}, and {why}")
    return calc


def _allocator(model):
    return lambda: AbstractValue.Make(model)
