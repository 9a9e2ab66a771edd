"""What the CAN station's camera and ground-truth ports show: the emulator's scene, or nothing.

The real arm reports joints and gripper only. Camera images come from a camera, and the
simulation-only outputs (`camera.label`, `body_poses`) exist only where there is a
simulation. With an emulator, its simulated scene is that world: `EmulatedScene` renders it
and reads its body poses. Without one, `NoScene` keeps the port contract but refuses to be
evaluated, naming the port. Camera drivers (a live or emulated RealSense) hang off either:
see `can_cameras`.
"""

from __future__ import annotations

from pydrake.common.value import AbstractValue
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.framework import Context, LeafSystem

from physcap_drake.can.emulator import PiperEmulator
from physcap_drake.can.simulated_motion import SimulatedMotion
from physcap_drake.station import ports
from physcap_drake.station.ports import camera_port

SCENE_OUTPUTS = (*ports.IMAGE_OUTPUTS, ports.BODY_POSES)
#: The images a rendered camera gives, and the name of the station's camera.
IMAGES = ("rgb", "depth", "label")
MAIN_CAMERA = "camera"


class EmulatedScene(LeafSystem):
    """`<camera>.rgb`, `<camera>.depth`, `<camera>.label` of each rendered camera in
    `cameras` (names of the emulator's simulated station's cameras; the station camera by
    default) and body_poses, all of the emulator's simulated scene.

    Each evaluation copies the scene's plant state (under the emulator's lock, so a
    consistent instant) into a context of its own and evaluates the simulated station's port
    there: rendering never holds up the emulator's firmware loop. The values are the same
    types as the sim station's. Body poses are in the world frame, indexed by BodyIndex of
    `motion.plant`; they and the label image are ground truth for success checks only.
    """

    def __init__(self, emulator: PiperEmulator, motion: SimulatedMotion,
                 cameras: tuple[str, ...] = (MAIN_CAMERA,)):
        super().__init__()
        self.emulator = emulator  # resources shared with the emulator thread, not state
        self.motion = motion
        self._render_context = motion.station.CreateDefaultContext()
        self._render_plant_context = motion.plant.GetMyMutableContextFromRoot(
            self._render_context)
        names = [camera_port(camera, image) for camera in cameras for image in IMAGES]
        for name in (*names, ports.BODY_POSES):
            port = motion.station.GetOutputPort(name)
            self.DeclareAbstractOutputPort(name, port.Allocate, self._copier(port),
                                           {self.time_ticket()})
        # The first image costs several times the next ones (renderer set-up): pay it now.
        for camera in cameras:
            motion.station.GetOutputPort(camera_port(camera, "rgb")).Eval(self._render_context)

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
    """Ports of a station without a simulation that keep the port contract but refuse to be
    evaluated, naming the port (see module docstring).

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
            self.DeclareAbstractOutputPort(name, allocate, self._refuse(name, why))

    @staticmethod
    def _refuse(name: str, why: str):
        def calc(context: Context, output: AbstractValue) -> None:
            what = ("simulation-only ground truth" if name == ports.BODY_POSES
                    or name.endswith(".label") else "a camera image")
            raise RuntimeError(f"{name} is {what}, and {why}")
        return calc


def _allocator(model):
    return lambda: AbstractValue.Make(model)
