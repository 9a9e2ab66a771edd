"""What the CAN station's camera and ground-truth ports show: the emulator's scene, or nothing.

The real arm reports joints and gripper only. Camera images come from a camera, and the
simulation-only outputs (`camera.label`, `body_poses`) exist only where there is a
simulation. With an emulator, its simulated scene is that world: `EmulatedScene` renders it
and reads its body poses. Without one, `NoScene` keeps the port contract but refuses to be
evaluated, naming the port (no camera driver is part of this project yet).
"""

from __future__ import annotations

from pydrake.common.value import AbstractValue
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.framework import Context, LeafSystem

from physcap_drake.can.emulator import PiperEmulator
from physcap_drake.can.simulated_motion import SimulatedMotion
from physcap_drake.station import ports

SCENE_OUTPUTS = (*ports.IMAGE_OUTPUTS, ports.BODY_POSES)


class EmulatedScene(LeafSystem):
    """camera.rgb, camera.depth, camera.label and body_poses of the emulator's simulated scene.

    Each evaluation copies the scene's plant state (under the emulator's lock, so a
    consistent instant) into a context of its own and evaluates the simulated station's port
    there: rendering never holds up the emulator's firmware loop. The values are the same
    types as the sim station's. Body poses are in the world frame, indexed by BodyIndex of
    `motion.plant`; they and the label image are ground truth for success checks only.
    """

    def __init__(self, emulator: PiperEmulator, motion: SimulatedMotion):
        super().__init__()
        self.emulator = emulator  # resources shared with the emulator thread, not state
        self.motion = motion
        self._render_context = motion.station.CreateDefaultContext()
        self._render_plant_context = motion.plant.GetMyMutableContextFromRoot(
            self._render_context)
        for name in SCENE_OUTPUTS:
            port = motion.station.GetOutputPort(name)
            self.DeclareAbstractOutputPort(name, port.Allocate, self._copier(port),
                                           {self.time_ticket()})
        # The first image costs several times the next ones (renderer set-up): pay it now.
        motion.station.GetOutputPort(ports.CAMERA_RGB).Eval(self._render_context)

    def _copier(self, port):
        def calc(context: Context, output: AbstractValue) -> None:
            self._sync()
            output.SetFrom(port.EvalAbstract(self._render_context))
        return calc

    def _sync(self) -> None:
        plant = self.motion.plant
        with self.emulator.lock:
            state = plant.GetPositionsAndVelocities(self.motion.plant_context)
        plant.SetPositionsAndVelocities(self._render_plant_context, state)


class NoScene(LeafSystem):
    """The scene ports of a station without a camera or a simulation (see module docstring)."""

    def __init__(self, camera_width: int, camera_height: int):
        super().__init__()
        from pydrake.systems.sensors import ImageDepth32F, ImageLabel16I, ImageRgba8U

        empty = MultibodyPlant(0.0)
        empty.Finalize()
        models = {ports.CAMERA_RGB: ImageRgba8U(camera_width, camera_height),
                  ports.CAMERA_DEPTH: ImageDepth32F(camera_width, camera_height),
                  ports.CAMERA_LABEL: ImageLabel16I(camera_width, camera_height)}
        for name in SCENE_OUTPUTS:
            if name == ports.BODY_POSES:
                allocate = empty.get_body_poses_output_port().Allocate
            else:
                allocate = (lambda model: lambda: AbstractValue.Make(model))(models[name])
            self.DeclareAbstractOutputPort(name, allocate, self._refuse(name))

    @staticmethod
    def _refuse(name: str):
        def calc(context: Context, output: AbstractValue) -> None:
            what = ("simulation-only ground truth" if name in ports.SIM_ONLY_OUTPUTS
                    else "a camera image")
            raise RuntimeError(f"{name} is {what}, and this PiperCan station has no "
                               "emulator (station.emulate: false) and no camera driver")
        return calc
