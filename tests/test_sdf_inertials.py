"""SDFormat inertials rewritten as text (a task's hidden masses, an as-built arm's links):
a link with no inertial mass, or an empty number, is refused naming it; a link without an
inertial pose keeps its centre of mass at its origin."""

from __future__ import annotations

import xml.etree.ElementTree as ET

import pytest

from physcap_drake.station.as_built import deviate_links
from physcap_drake.station.body_masses import with_masses
from physcap_drake.station.sim_config import AsBuilt, LinkDeviation

INERTIA = ("<inertia><ixx>0.002</ixx><iyy>0.004</iyy><izz>0.006</izz><ixy>0</ixy><ixz>0</ixz>"
           "<iyz>0</iyz></inertia>")


def model(inertial: str) -> str:
    return f'<sdf version="1.9"><model name="m"><link name="box">{inertial}</link></model></sdf>'


def test_a_link_without_inertial_mass_is_refused_naming_it():
    for bare in ("", "<inertial>" + INERTIA + "</inertial>"):
        with pytest.raises(ValueError, match=r"'m::box': the model gives the body no mass"):
            with_masses(model(bare), {"box": 0.25}, "m")
        with pytest.raises(ValueError, match=r"links.box: arm gives the link 'box' no inertial "
                                             "mass to scale"):
            deviate_links(model(bare), AsBuilt(links={"box": LinkDeviation(mass_scale=2.0)}),
                          "arm")


def test_an_empty_number_is_refused_naming_its_element():
    empty_mass = model("<inertial><mass/>" + INERTIA + "</inertial>")
    with pytest.raises(ValueError, match="<mass> holds no number"):
        with_masses(empty_mass, {"box": 0.25}, "m")
    empty_moment = model("<inertial><mass>0.5</mass>" + INERTIA.replace("0.004", "")
                         + "</inertial>")
    with pytest.raises(ValueError, match="<iyy> holds no number"):
        with_masses(empty_moment, {"box": 0.25}, "m")


def test_deviated_links_scale_mass_inertia_and_the_centre_of_mass_given():
    links = {"box": LinkDeviation(mass_scale=2.0, com_scale=[1.0, 0.5, 3.0])}
    posed = model("<inertial><pose>0.1 0.2 0.3 0 0 0</pose><mass>0.5</mass>" + INERTIA
                  + "</inertial>")
    root = ET.fromstring(deviate_links(posed, AsBuilt(links=links), "arm"))
    assert float(root.find(".//mass").text) == 1.0
    assert [float(m.text) for m in root.find(".//inertia")] == pytest.approx(
        [0.004, 0.008, 0.012, 0, 0, 0])
    assert [float(v) for v in root.find(".//pose").text.split()] == pytest.approx(
        [0.1, 0.1, 0.9, 0, 0, 0])
    # Without an inertial pose the centre of mass is the link's origin: nothing to scale.
    unposed = model("<inertial><mass>0.5</mass>" + INERTIA + "</inertial>")
    root = ET.fromstring(deviate_links(unposed, AsBuilt(links=links), "arm"))
    assert float(root.find(".//mass").text) == 1.0 and root.find(".//pose") is None
