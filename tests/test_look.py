"""`physcap look` on an emulated rig: the objects perception finds, where the simulator
put them, with the arm left as it was."""

from __future__ import annotations

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from physcap_drake.app.scene_layout import object_position
from physcap_drake.cli import app
from physcap_drake.resources import stations_dir
from physcap_drake.scenario import load_scenario
from physcap_drake.tasks.registry import get_task

TWIN = stations_dir() / "identify_empty_can_rig_emulated.yaml"
#: How far (m) a listed object may be from where the simulator placed it.
TOLERANCE = 0.01


@pytest.mark.emulated_hardware
def test_look_lists_the_cans_and_the_tray_where_the_simulator_put_them(tmp_path):
    out, png = tmp_path / "look.json", tmp_path / "look.png"
    result = CliRunner().invoke(app, ["look", "--scenario", str(TWIN), "--json", str(out),
                                      "--png", str(png)])
    assert result.exit_code == 0, result.output
    listed = {row["name"]: row for row in json.loads(out.read_text())["objects"]}
    scenario = load_scenario(TWIN)
    instance = get_task("identify_empty_can").instance(scenario.random_seed,
                                                       scenario.task.answer)
    truth = {obj.visible.name: np.array(obj.xy) for obj in instance.objects}
    truth["brown tray"] = object_position(scenario, "tray")[:2]
    assert sorted(listed) == sorted(truth)
    for name, xy in truth.items():
        assert np.linalg.norm(np.array(listed[name]["position_m"]) - xy) < TOLERANCE, name
    assert all(0.10 < listed[name]["height_m"] < 0.14 for name in truth if "can" in name)
    assert listed["red can"]["category"] == "can" and listed["red can"]["color"] == "red"
    assert png.stat().st_size > 10_000
    assert json.loads(out.read_text())["joints_rad"] == pytest.approx([0.0] * 6, abs=1e-3)


def test_look_refuses_the_simulated_station():
    result = CliRunner().invoke(app, ["look", "--scenario",
                                      str(stations_dir() / "identify_empty_can.yaml")])
    assert result.exit_code == 2 and "physcap task show" in result.output
