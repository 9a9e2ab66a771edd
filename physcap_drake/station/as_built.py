"""Building the simulated world as built rather than as drawn (`station.as_built`), and
with its hidden masses (`Scenario.body_masses`, see `body_masses`).

Design notes: docs/design/station.md.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Mapping

from pydrake.geometry import ProximityProperties, RoleAssign
from pydrake.multibody.parsing import FlattenModelDirectives, ModelDirectives
from pydrake.multibody.plant import MultibodyPlant

from physcap_drake.resources import make_package_map
from physcap_drake.station.body_masses import (
    element_number,
    mass_texts,
    scale_moments_of_inertia,
)
from physcap_drake.station.directive_loader import load_directives, sdf_text
from physcap_drake.station.sim_config import AsBuilt


def add_directives_as_built(plant: MultibodyPlant, directives: list, arm_model: str,
                            as_built: AsBuilt, masses: Mapping[str, float] | None = None
                            ) -> None:
    """Adds the models of `directives` to `plant` like `robot_model.add_directives`, the arm
    model `arm_model` with the link deviations and joint damping of `as_built`, and the
    bodies named in `masses` (kg by scoped body name) with those masses (`body_masses`)."""
    texts = _as_built_arm(directives, arm_model, as_built)
    load_directives(plant, directives, texts=mass_texts(directives, masses or {}, texts))


def _as_built_arm(directives: list, arm_model: str, as_built: AsBuilt) -> dict[str, str]:
    """{arm_model: its model's text as built}, or nothing for an arm as drawn."""
    if not as_built.links and not as_built.joint_damping:
        return {}
    flat = FlattenModelDirectives(ModelDirectives(directives=directives), make_package_map())
    arm = [d.add_model for d in flat.directives
           if d.add_model is not None and d.add_model.name == arm_model]
    field = "links" if as_built.links else "joint_damping"
    if not arm:
        raise ValueError(f"station.as_built.{field}: no model named {arm_model!r} in the "
                         "scenario's directives")
    path = make_package_map().ResolveUrl(arm[0].file)
    text = sdf_text(path)
    if text is None:
        raise ValueError(f"station.as_built.{field}: the arm's model {path} includes other "
                         "files; an as-built arm needs a model in one file")
    return {arm_model: damp_joints(deviate_links(text, as_built, path), as_built.joint_damping,
                                   path)}


def deviate_links(sdf: str, as_built: AsBuilt, label: str) -> str:
    """The SDF text with each named link's inertial mass, inertia and centre of mass
    scaled as `as_built.links` says (unchanged without links)."""
    if not as_built.links:
        return sdf
    root = ET.fromstring(sdf)
    links = {link.get("name", ""): link for link in root.iter("link")}
    for name, deviation in as_built.links.items():
        if name not in links:
            raise ValueError(f"station.as_built.links.{name}: {label} has no link {name!r} "
                             f"(links: {', '.join(sorted(links))})")
        inertial = links[name].find("inertial")
        mass = inertial.find("mass") if inertial is not None else None
        if inertial is None or mass is None:
            raise ValueError(f"station.as_built.links.{name}: {label} gives the link "
                             f"{name!r} no inertial mass to scale")
        mass.text = repr(element_number(mass) * deviation.mass_scale)
        scale_moments_of_inertia(inertial, deviation.mass_scale)
        pose = inertial.find("pose")
        if pose is None or not pose.text:  # the centre of mass is the link's origin
            continue
        values = [float(v) for v in pose.text.split()]
        values[:3] = [v * s for v, s in zip(values[:3], deviation.com_scale, strict=True)]
        pose.text = " ".join(repr(v) for v in values)
    return ET.tostring(root, encoding="unicode")


def damp_joints(sdf: str, damping: list[float], label: str) -> str:
    """The SDF text with viscous damping `damping` (N·m·s/rad, J1..J6) on its revolute
    joints, in the order the file declares them (unchanged for an empty list)."""
    if not damping:
        return sdf
    root = ET.fromstring(sdf)
    joints = [j for j in root.iter("joint") if j.get("type") in ("revolute", "continuous")]
    if len(joints) != len(damping):
        raise ValueError(f"station.as_built.joint_damping: {len(damping)} values for the "
                         f"{len(joints)} revolute joints of {label}")
    for joint, value in zip(joints, damping, strict=True):
        axis = joint.find("axis")
        if axis is None:
            axis = ET.SubElement(joint, "axis")
        dynamics = axis.find("dynamics")
        if dynamics is None:
            dynamics = ET.SubElement(axis, "dynamics")
        element = dynamics.find("damping")
        if element is None:
            element = ET.SubElement(dynamics, "damping")
        element.text = repr(float(value))
    return ET.tostring(root, encoding="unicode")


def scale_moduli(plant: MultibodyPlant, scene_graph, scales: dict[str, float]) -> None:
    """Scales the hydroelastic modulus of the compliant geometries of each named model."""
    inspector = scene_graph.model_inspector()
    for name, scale in scales.items():
        if not plant.HasModelInstanceNamed(name):
            raise ValueError(f"station.as_built.modulus_scale: no model named {name!r}")
        instance = plant.GetModelInstanceByName(name)
        scaled = 0
        for index in plant.GetBodyIndices(instance):
            for geometry in plant.GetCollisionGeometriesForBody(plant.get_body(index)):
                old = inspector.GetProximityProperties(geometry)
                if not old.HasProperty("hydroelastic", "hydroelastic_modulus"):
                    continue
                new = ProximityProperties(old)
                modulus = old.GetProperty("hydroelastic", "hydroelastic_modulus")
                new.UpdateProperty("hydroelastic", "hydroelastic_modulus", modulus * scale)
                scene_graph.AssignRole(plant.get_source_id(), geometry, new,
                                       RoleAssign.kReplace)
                scaled += 1
        if not scaled:
            raise ValueError(f"station.as_built.modulus_scale.{name}: the model has no "
                             "compliant hydroelastic geometry")
