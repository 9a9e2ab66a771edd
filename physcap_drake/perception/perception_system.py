"""PerceptionSystem: the camera's one route to the objects in view, a system in the diagram.

The AgentSystem reads its outputs through its input ports; `get_object_pose` and the camera
judge evaluate them in the diagram's Context. Design notes: docs/design/perception.md.
"""

from __future__ import annotations

import dataclasses as dc
import hashlib

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import Context, LeafSystem
from pydrake.systems.sensors import ImageDepth32F, ImageLabel16I, ImageRgba8U

from physcap_drake.perception.camera_geometry import CameraGeometry
from physcap_drake.perception.object_geometry import SteadySizes, measure
from physcap_drake.perception.seen_object import SeenObject
from physcap_drake.perception.visible_objects import VisibleObject
from physcap_drake.station import ports
from physcap_drake.weak_method import weak_method

VIEW_PORT = "perception.view"
SIZES_PORT = "perception.sizes"
#: The value type of each image input a perception module may read.
IMAGE_INPUTS = {ports.CAMERA_RGB: ImageRgba8U, ports.CAMERA_DEPTH: ImageDepth32F,
                ports.CAMERA_LABEL: ImageLabel16I}


@dc.dataclass(frozen=True)
class PerceptionView:
    """One look: the objects in view, left to right (`SeenObject`: attributes, grasp point,
    footprint, world frame, m), every object named so far (`known`), the colour image
    (H × W × 4) and depth image (H × W, m) it was found in, and `frame`, a digest of both
    images (equal digests: the same frame)."""

    objects: tuple[SeenObject, ...] = ()
    known: tuple[VisibleObject, ...] = ()
    rgb: np.ndarray = dc.field(default_factory=lambda: np.zeros((0, 0, 4), np.uint8))
    depth: np.ndarray = dc.field(default_factory=lambda: np.zeros((0, 0), np.float32))
    frame: bytes = b""


class PerceptionMemory:
    """What perception keeps between looks, in the system's Context: the perception module
    (its object memory, container areas and last look) and the sizes stated so far."""

    def __init__(self, module):
        self.module = module
        self.sizes = SteadySizes()


class PerceptionSystem(LeafSystem):
    """Finds the objects in view with a perception module (an RgbdPerception, or the
    simulator's LabelPerception: `look(images)`, `known()`, `input_ports`, `camera`), once
    per frame looked at: the outputs are computed when evaluated and cached by Drake until an
    input changes (the agent looks at discrete events, not every step).

    Input ports (the module's `input_ports`, named as the station's outputs):
        camera.rgb, camera.depth (images): what the camera shows; depth in m.
        camera.label (image): the simulator's segmenter, for LabelPerception only.
        piper.position_measured (6): measured joints, rad, for RgbdPerception only (to
            leave the arm out of the view).
    Output ports:
        perception.view (PerceptionView): the objects in view, with the images they were
            found in.
        perception.sizes (tuple of object_geometry.Geometry): each object's size (m) in
            the order of the view's objects, held across the looks that read this port
            (SteadySizes; the agent's observations).
    State (abstract, advanced by the looks, i.e. by evaluating the outputs):
        PerceptionMemory: the module with its object memory, and the stated sizes.
    """

    def __init__(self, module):
        super().__init__()
        self._camera = module.camera
        self._inputs = {}
        for name in module.input_ports:
            if name in IMAGE_INPUTS:
                self._inputs[name] = self.DeclareAbstractInputPort(
                    name, AbstractValue.Make(IMAGE_INPUTS[name]()))
            else:
                self._inputs[name] = self.DeclareVectorInputPort(name, ports.VECTOR_OUTPUTS[name])
        self._memory = self.DeclareAbstractState(AbstractValue.Make(PerceptionMemory(module)))
        self._view = self.DeclareAbstractOutputPort(
            VIEW_PORT, lambda: AbstractValue.Make(PerceptionView()), weak_method(self._calc_view))
        self.DeclareAbstractOutputPort(SIZES_PORT, lambda: AbstractValue.Make(()),
                                       weak_method(self._calc_sizes))

    @property
    def camera(self) -> CameraGeometry:
        """The calibrated camera the objects are seen with."""
        return self._camera

    def memory(self, context: Context) -> PerceptionMemory:
        return context.get_abstract_state(self._memory).get_value()

    def look(self, context: Context) -> PerceptionView:
        """The view now (the `perception.view` output in this system's `context`)."""
        return self._view.Eval(context)

    def _calc_view(self, context: Context, output: AbstractValue) -> None:
        images = {name: (port.Eval(context).data if name in IMAGE_INPUTS else port.Eval(context))
                  for name, port in self._inputs.items()}
        module = self.memory(context).module
        seen = module.look(images)
        rgb = np.array(images[ports.CAMERA_RGB], copy=True)
        depth = np.array(images[ports.CAMERA_DEPTH], copy=True).reshape(rgb.shape[:2])
        digest = hashlib.blake2b(np.ascontiguousarray(rgb).tobytes(), digest_size=16)
        digest.update(np.ascontiguousarray(images[ports.CAMERA_DEPTH]).tobytes())
        output.set_value(PerceptionView(tuple(seen), tuple(module.known()), rgb, depth,
                                        digest.digest()))

    def _calc_sizes(self, context: Context, output: AbstractValue) -> None:
        view = self.look(context)
        shapes = []
        if view.objects:
            shapes = measure(list(view.objects), view.depth.astype(np.float64), self._camera)
        sizes = self.memory(context).sizes
        output.set_value(tuple(sizes.steady(s.name, g)
                               for s, g in zip(view.objects, shapes, strict=True)))
