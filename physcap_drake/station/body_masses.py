"""A simulated world's hidden masses, as model data of its plant.

Design notes: docs/design/station.md.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Mapping

from pydrake.multibody.parsing import FlattenModelDirectives, ModelDirectives

from physcap_drake.resources import make_package_map
from physcap_drake.station.directive_loader import sdf_text


def masses_by_model(masses: Mapping[str, float]) -> dict[str, dict[str, float]]:
    """`masses` (kg by scoped body name, "model_instance::body") grouped by model instance:
    {model: {body: kg}}. Raises ValueError naming a name that is not scoped or a mass that
    is not positive."""
    grouped: dict[str, dict[str, float]] = {}
    for name, kg in masses.items():
        instance, sep, link = name.rpartition("::")
        if not sep or not instance or not link:
            raise ValueError(f"body_masses: {name!r} is not a scoped body name "
                             "(\"model_instance::body\", e.g. \"red_can::can_red_open\")")
        if not float(kg) > 0.0:
            raise ValueError(f"body_masses[{name!r}] must be a positive mass in kg; got {kg}")
        grouped.setdefault(instance, {})[link] = float(kg)
    return grouped


def with_masses(sdf: str, masses: Mapping[str, float], model: str) -> str:
    """The SDFormat text `sdf` of model instance `model` with each named link's mass set to
    `masses[link]` kg and its moments of inertia scaled by the same factor (the centre of
    mass stays). Raises ValueError naming a link the model does not have or one without an
    inertial mass."""
    root = ET.fromstring(sdf)
    links = {link.get("name", ""): link for link in root.iter("link")}
    for link_name, kg in masses.items():
        scoped = f"{model}::{link_name}"
        if link_name not in links:
            raise ValueError(f"body_masses: {scoped!r} names the body {link_name!r}, which "
                             f"the model instance {model!r} does not have")
        inertial = links[link_name].find("inertial")
        mass = inertial.find("mass") if inertial is not None else None
        if inertial is None or mass is None or not element_number(mass) > 0.0:
            raise ValueError(f"body_masses: {scoped!r}: the model gives the body no mass "
                             "to replace")
        scale_moments_of_inertia(inertial, kg / element_number(mass))
        mass.text = repr(kg)
    return ET.tostring(root, encoding="unicode")


def scale_moments_of_inertia(inertial: ET.Element, scale: float) -> None:
    """Multiplies the moments and products of inertia of an SDFormat `<inertial>` element by
    `scale` (as a mass scaled by it with the same shape has them)."""
    inertia = inertial.find("inertia")
    for moment in (inertia if inertia is not None else ()):
        moment.text = repr(element_number(moment) * scale)


def element_number(element: ET.Element) -> float:
    """The number an SDFormat element holds. Raises ValueError naming an empty one."""
    if element.text is None:
        raise ValueError(f"the SDFormat element <{element.tag}> holds no number")
    return float(element.text)


def mass_texts(directives: list, masses: Mapping[str, float],
               texts: Mapping[str, str] | None = None) -> dict[str, str]:
    """SDFormat text, by model instance name, of each model of `directives` that `masses`
    (kg by scoped body name) weighs differently, for `directive_loader.load_directives`;
    `texts`: models already given as text (e.g. the arm as built), the base of theirs.
    Raises ValueError naming a model instance the directives do not add, one that is not a
    single SDFormat file, and the errors of `masses_by_model` and `with_masses`."""
    grouped = masses_by_model(masses)
    if not grouped:
        return dict(texts or {})
    package_map = make_package_map()
    files = {d.add_model.name: d.add_model.file for d in FlattenModelDirectives(
        ModelDirectives(directives=directives), package_map).directives
        if d.add_model is not None}
    result = dict(texts or {})
    for model, links in grouped.items():
        if model not in files:
            name = f"{model}::{next(iter(links))}"
            raise ValueError(f"body_masses: {name!r} names the model instance {model!r}, "
                             "which the simulated world does not have")
        text = result.get(model)
        if text is None:
            file = files[model]
            path = package_map.ResolveUrl(file) if "://" in file else file
            text = sdf_text(path) if path.endswith(".sdf") else None
            if text is None:
                raise ValueError(f"body_masses: the model instance {model!r} ({file}) is not "
                                 "one SDFormat file, so its masses cannot be given")
        result[model] = with_masses(text, links, model)
    return result
