"""The cameras' own copy of the simulated world, kept warm from one station to the next.

Design notes: docs/design/station.md.
"""

from __future__ import annotations

import dataclasses as dc
import itertools
import os
import threading

from pydrake.common.value import AbstractValue
from pydrake.common.yaml import yaml_dump_typed
from pydrake.geometry import (
    FrameId,
    FramePoseVector,
    GeometryFrame,
    GeometryId,
    GeometryInstance,
    MakeRenderEngineGl,
    MakeRenderEngineVtk,
    QueryObject,
    RenderEngineGlParams,
    RenderEngineVtkParams,
    Role,
    SceneGraph,
    SceneGraphInspector,
)
from pydrake.math import RigidTransform
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.sensors import CameraConfig

#: Frames a new world has for the bodies it follows (more when a scene needs more).
FRAMES = 64
#: Idle worlds kept per process, thread and set of renderers, and in all.
IDLE_WORLDS = 2
IDLE_WORLDS_IN_ALL = 4


@dc.dataclass(frozen=True)
class RendererSpec:
    """One named render engine: the scenario camera's `renderer_name` and the parameters of
    its `renderer_class`."""

    name: str
    params: RenderEngineVtkParams | RenderEngineGlParams

    @property
    def key(self) -> tuple[str, str, str]:
        """What makes two specs the same engine (name, type and every parameter, exactly)."""
        return self.name, type(self.params).__name__, yaml_dump_typed(self.params)

    def make(self):
        """A new render engine of this spec."""
        if isinstance(self.params, RenderEngineGlParams):
            return MakeRenderEngineGl(self.params)
        return MakeRenderEngineVtk(self.params)


def renderer_spec(config: CameraConfig) -> RendererSpec:
    """The render engine camera `config` asks for. Raises ValueError for a `renderer_class`
    that is neither VTK nor GL parameters (nor their names)."""
    renderer = config.renderer_class
    if isinstance(renderer, RenderEngineVtkParams | RenderEngineGlParams):
        return RendererSpec(config.renderer_name, renderer)
    if renderer in ("", "RenderEngineVtk"):
        return RendererSpec(config.renderer_name, RenderEngineVtkParams(backend="EGL"))
    if renderer == "RenderEngineGl":
        return RendererSpec(config.renderer_name, RenderEngineGlParams())
    raise ValueError(
        f"camera '{config.name}': renderer_class {renderer!r} is not supported; use "
        "!RenderEngineVtkParams {backend: EGL} (headless) or !RenderEngineGlParams {}")


def unique_renderers(configs: list[CameraConfig]) -> tuple[RendererSpec, ...]:
    """One spec per renderer name of `configs`, the first camera's where cameras share a name
    (as SceneGraph keeps the first renderer added under a name)."""
    specs: dict[str, RendererSpec] = {}
    for config in configs:
        specs.setdefault(config.renderer_name, renderer_spec(config))
    return tuple(specs.values())


class RenderWorld:
    """A SceneGraph of the cameras' own, with its renderers, showing one station's scene at a
    time (see the design notes). Not a system: the cameras (`RenderCamera`) call it when
    their images are evaluated; it keeps no state of the station's simulation."""

    def __init__(self, renderers: tuple[RendererSpec, ...], frames: int):
        builder = DiagramBuilder()
        self._scene_graph = builder.AddSystem(SceneGraph())
        self._source = self._scene_graph.RegisterSource("render_world")
        self._frames = [self._scene_graph.RegisterFrame(self._source, GeometryFrame(f"body_{i}"))
                        for i in range(frames)]
        for spec in renderers:
            self._scene_graph.AddRenderer(spec.name, spec.make())
        self._diagram = builder.Build()
        self._context = self._scene_graph.GetMyMutableContextFromRoot(
            self._diagram.CreateDefaultContext())
        self._poses_port = self._scene_graph.get_source_pose_port(self._source)
        self._poses = FramePoseVector()
        for frame in self._frames:
            self._poses.set_value(frame, RigidTransform())
        self.key = _key(renderers)
        #: What each frame (the world frame for anchored geometry) holds: the signature of
        #: the body it was registered for and the registered geometries.
        self._held: dict[FrameId, tuple[tuple | None, list[GeometryId]]] = {}
        self._bodies: list[tuple[int, FrameId]] = []
        self._showing = False
        self.registered = 0  # geometries registered over the world's life

    @property
    def capacity(self) -> int:
        """How many moving bodies the world can follow."""
        return len(self._frames)

    def show(self, plant: MultibodyPlant, inspector: SceneGraphInspector) -> None:
        """Shows a copy of every perception geometry of `plant`'s SceneGraph (`inspector`), each
        moving body's on a frame of its own. A frame that holds exactly a body's geometry
        (shapes, poses in the body, perception properties with the render label) from the
        station before follows that body again without registering anything; the rest of
        the previous station's geometry is removed. Raises ValueError when the world already
        shows a scene or has too few frames."""
        if self._showing:
            raise ValueError("this render world already shows a scene; release it first")
        scene = _visible_geometry(plant, inspector)
        world = inspector.world_frame_id()
        moving = [body for body in scene if body != _WORLD_BODY]
        if len(moving) > len(self._frames):
            raise ValueError(f"the scene has {len(moving)} moving bodies with visible "
                             f"geometry; this render world follows {len(self._frames)}")
        signatures = {body: _signature(inspector, ids) for body, ids in scene.items()}
        slots: dict[int, FrameId] = {}
        for body, signature in signatures.items():
            candidates = [world] if body == _WORLD_BODY else self._frames
            same = (frame for frame in candidates if frame not in slots.values()
                    and signature is not None and self._held.get(frame, (None,))[0] == signature)
            frame = next(same, None)
            if frame is not None:
                slots[body] = frame
        for frame in [frame for frame in self._held if frame not in slots.values()]:
            for geometry in self._held.pop(frame)[1]:
                self._scene_graph.RemoveGeometry(self._context, self._source, geometry)
        free = iter(frame for frame in self._frames if frame not in slots.values())
        for body, geometries in scene.items():
            if body in slots:
                continue
            slots[body] = world if body == _WORLD_BODY else next(free)
            self._held[slots[body]] = (signatures[body], [
                self._register(inspector, geometry, slots[body]) for geometry in geometries])
        self._bodies = [(body, frame) for body, frame in slots.items() if body != _WORLD_BODY]
        self._showing = True

    def query(self, body_poses: list[RigidTransform]) -> QueryObject:
        """The world's query object with each frame at its body's pose in `body_poses` (the
        plant's `body_poses` output: X_WB by body index); render images through it."""
        for body, frame in self._bodies:
            self._poses.set_value(frame, body_poses[body])
        self._poses_port.FixValue(self._context, AbstractValue.Make(self._poses))
        return self._scene_graph.get_query_output_port().Eval(self._context)

    def hide(self) -> None:
        """Stops showing the station's scene: its frames follow no body any more. The
        geometry stays registered until the next `show`, which keeps what it can use."""
        self._bodies = []
        self._showing = False

    def _register(self, inspector: SceneGraphInspector, geometry: GeometryId,
                  frame: FrameId) -> GeometryId:
        copy = GeometryInstance(inspector.GetPoseInFrame(geometry),
                                inspector.GetShape(geometry), inspector.GetName(geometry))
        copy.set_perception_properties(inspector.GetPerceptionProperties(geometry))
        self.registered += 1
        return self._scene_graph.RegisterGeometry(self._context, self._source, frame, copy)


#: The world body's index: its geometry is anchored.
_WORLD_BODY = 0


def _visible_geometry(plant: MultibodyPlant,
                      inspector: SceneGraphInspector) -> dict[int, list[GeometryId]]:
    """Perception geometries of `plant` by body index (the world body first, then in the order
    of each body's first geometry)."""
    world = inspector.world_frame_id()
    scene: dict[int, list[GeometryId]] = {_WORLD_BODY: []}
    for geometry in inspector.GetAllGeometryIds(Role.kPerception):
        frame = inspector.GetFrameId(geometry)
        body = _WORLD_BODY if frame == world else int(plant.GetBodyFromFrameId(frame).index())
        scene.setdefault(body, []).append(geometry)
    return scene


def _signature(inspector: SceneGraphInspector, geometries: list[GeometryId]) -> tuple | None:
    """What a renderer sees of a body's `geometries`: each one's shape, pose in the body's
    frame and perception properties. None if a property's value cannot be read here (such
    a body's geometry is always registered afresh)."""
    signature = []
    for geometry in geometries:
        properties = inspector.GetPerceptionProperties(geometry)
        values = []
        for group in sorted(properties.GetGroupNames()):
            for name, value in sorted(properties.GetPropertiesInGroup(group).items()):
                try:
                    values.append((group, name, repr(value.get_value())))
                except (TypeError, RuntimeError):  # a value type pydrake does not bind
                    return None
        signature.append((repr(inspector.GetShape(geometry)),
                          inspector.GetPoseInFrame(geometry).GetAsMatrix34().tobytes(),
                          tuple(values)))
    return tuple(signature)


_threads = threading.local()
_thread_numbers = itertools.count()


def _key(renderers: tuple[RendererSpec, ...]) -> tuple:
    """(process, thread, renderers): a world is lent again only to the thread it was made in
    (an EGL context current in one thread cannot be made current in another), and never
    across a fork. Threads are numbered by this module, as a finished thread's identifier
    is given to later threads."""
    if not hasattr(_threads, "number"):
        _threads.number = next(_thread_numbers)
    return os.getpid(), _threads.number, tuple(sorted(spec.key for spec in renderers))


class _Pool:
    """Idle render worlds by key (`_key`), the least recently returned dropped first."""

    def __init__(self) -> None:
        self._idle: dict[tuple, list[RenderWorld]] = {}
        self._returned: list[RenderWorld] = []
        self._lock = threading.Lock()

    def take(self, key: tuple, frames: int) -> RenderWorld | None:
        with self._lock:
            idle = self._idle.get(key, [])
            for world in idle:
                if world.capacity >= frames:
                    idle.remove(world)
                    self._returned.remove(world)
                    return world
        return None

    def give_back(self, world: RenderWorld) -> None:
        with self._lock:
            same_key = self._idle.get(world.key, [])
            if len(same_key) == IDLE_WORLDS:
                self._forget(same_key[0])
            if len(self._returned) == IDLE_WORLDS_IN_ALL:
                self._forget(self._returned[0])
            self._idle.setdefault(world.key, []).append(world)
            self._returned.append(world)

    def _forget(self, world: RenderWorld) -> None:
        self._idle[world.key].remove(world)
        self._returned.remove(world)
        if not self._idle[world.key]:
            del self._idle[world.key]

    def idle(self) -> int:
        """How many worlds wait in the pool (all keys)."""
        with self._lock:
            return len(self._returned)

    def drop(self) -> None:
        """Forgets every idle world."""
        with self._lock:
            self._idle.clear()
            self._returned.clear()


_POOL = _Pool()


class RenderWorldLease:
    """One station's use of a render world, from `lease_render_world` to `release` (which
    `close_station` calls). Its cameras share it."""

    def __init__(self, world: RenderWorld):
        self._world: RenderWorld | None = world

    @property
    def released(self) -> bool:
        return self._world is None

    @property
    def world(self) -> RenderWorld:
        """The world. Raises RuntimeError after `release` (it may show another station)."""
        if self._world is None:
            raise RuntimeError("the station was closed, so its render world went back to "
                               "the pool")
        return self._world

    def release(self) -> None:
        """Stops the world showing the station's scene and gives it back to the pool for
        the next station of this process and thread. Safe to call twice."""
        if self._world is not None:
            world, self._world = self._world, None
            world.hide()
            _POOL.give_back(world)


def lease_render_world(plant: MultibodyPlant, inspector: SceneGraphInspector,
                       renderers: tuple[RendererSpec, ...]) -> RenderWorldLease:
    """A render world with `renderers`, showing the visible geometry of `plant` (finalized,
    registered with the SceneGraph of `inspector`): an idle one of this process and thread
    when there is one, else a new one. Release the lease when the station closes."""
    frames = len(_visible_geometry(plant, inspector)) - 1  # not the world body
    world = _POOL.take(_key(renderers), frames) or RenderWorld(renderers, max(FRAMES, frames))
    world.show(plant, inspector)
    return RenderWorldLease(world)


def idle_render_worlds() -> int:
    """How many render worlds wait in this process's pool."""
    return _POOL.idle()


def drop_idle_render_worlds() -> None:
    """Frees the pool's idle render worlds (their engines and memory)."""
    _POOL.drop()
