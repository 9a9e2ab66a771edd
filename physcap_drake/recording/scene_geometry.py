"""The simulated scene's geometry as a Foxglove SceneUpdate.

Each body's illustration geometry becomes one scene entity locked to the body's frame (named
by `body_frame_name`), so the 3D panel moves it with the recorded transforms. Shapes map to
Foxglove primitives: boxes to cubes, cylinders to cylinders, spheres and ellipsoids to spheres
(an ellipsoid is a sphere with unequal sizes), capsules to a cylinder with two sphere caps.
Shapes with no primitive (meshes, half spaces) are listed in the entity's metadata as skipped.
"""

from __future__ import annotations

from foxglove.messages import (
    Color,
    CubePrimitive,
    CylinderPrimitive,
    KeyValuePair,
    Pose,
    Quaternion,
    SceneEntity,
    SceneUpdate,
    SpherePrimitive,
    Timestamp,
    Vector3,
)
from pydrake.geometry import Box, Capsule, Cylinder, Ellipsoid, Rgba, Role, Sphere
from pydrake.math import RigidTransform
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import Body, BodyIndex

_DEFAULT_COLOR = Rgba(0.7, 0.7, 0.7, 1.0)


def body_frame_name(plant: MultibodyPlant, body: Body) -> str:
    """The recorded frame of a body: "world", or "<model instance>::<body>"."""
    if body.index() == plant.world_body().index():
        return "world"
    return f"{plant.GetModelInstanceName(body.model_instance())}::{body.name()}"


def _pose(X: RigidTransform) -> Pose:
    p, q = X.translation(), X.rotation().ToQuaternion()
    return Pose(position=Vector3(x=p[0], y=p[1], z=p[2]),
                orientation=Quaternion(x=q.x(), y=q.y(), z=q.z(), w=q.w()))


def _color(rgba: Rgba) -> Color:
    return Color(r=rgba.r(), g=rgba.g(), b=rgba.b(), a=rgba.a())


def _add_shape(primitives: dict[str, list], shape, X_BG: RigidTransform, color: Color) -> bool:
    """Appends the primitives of one shape (pose X_BG in the body frame B, metres) to
    `primitives` (lists by kind: cubes, cylinders, spheres); False if the shape has none."""
    if isinstance(shape, Box):
        primitives["cubes"].append(CubePrimitive(pose=_pose(X_BG), color=color, size=Vector3(
            x=shape.width(), y=shape.depth(), z=shape.height())))
    elif isinstance(shape, Cylinder):
        d = 2.0 * shape.radius()
        primitives["cylinders"].append(CylinderPrimitive(
            pose=_pose(X_BG), color=color, size=Vector3(x=d, y=d, z=shape.length()),
            bottom_scale=1.0, top_scale=1.0))
    elif isinstance(shape, Sphere):
        d = 2.0 * shape.radius()
        primitives["spheres"].append(SpherePrimitive(pose=_pose(X_BG), color=color,
                                              size=Vector3(x=d, y=d, z=d)))
    elif isinstance(shape, Ellipsoid):
        primitives["spheres"].append(SpherePrimitive(pose=_pose(X_BG), color=color, size=Vector3(
            x=2.0 * shape.a(), y=2.0 * shape.b(), z=2.0 * shape.c())))
    elif isinstance(shape, Capsule):
        _add_shape(primitives, Cylinder(shape.radius(), shape.length()), X_BG, color)
        for sign in (-1.0, 1.0):
            X_GC = RigidTransform([0.0, 0.0, sign * shape.length() / 2.0])
            _add_shape(primitives, Sphere(shape.radius()), X_BG @ X_GC, color)
    else:
        return False
    return True


def scene_update(plant: MultibodyPlant, scene_graph,
                 stamp: Timestamp | None = None) -> SceneUpdate:
    """One entity per body that has illustration geometry, locked to the body's frame, each
    stamped `stamp` (the message's log time; default the Unix epoch)."""
    stamp = stamp if stamp is not None else Timestamp(sec=0, nsec=0)
    inspector = scene_graph.model_inspector()
    entities = []
    for index in range(plant.num_bodies()):
        body = plant.get_body(BodyIndex(index))
        frame_id = plant.GetBodyFrameIdIfExists(body.index())
        if frame_id is None:
            continue
        name = body_frame_name(plant, body)
        primitives: dict[str, list] = {"cubes": [], "cylinders": [], "spheres": []}
        skipped = []
        for geometry in inspector.GetGeometries(frame_id, Role.kIllustration):
            properties = inspector.GetIllustrationProperties(geometry)
            rgba = properties.GetPropertyOrDefault("phong", "diffuse", _DEFAULT_COLOR)
            shape = inspector.GetShape(geometry)
            if not _add_shape(primitives, shape, inspector.GetPoseInFrame(geometry),
                              _color(rgba)):
                skipped.append(f"{inspector.GetName(geometry)} ({type(shape).__name__})")
        if any(primitives.values()):
            metadata = [KeyValuePair(key="skipped", value=", ".join(skipped))] if skipped else []
            entities.append(SceneEntity(timestamp=stamp, frame_id=name, id=name,
                                        frame_locked=True, metadata=metadata, **primitives))
    return SceneUpdate(entities=entities)
