"""The object library: families pick the shipped models the four tasks load, and write the
models a task asks for by data (boxes, balls, avocados of other levels) into the cache, each
a valid body standing on z = 0 whose looks do not show its stiffness."""

from __future__ import annotations

import pytest
from pydrake.geometry import Role
from test_object_models import _geometries, _load, _z_extent

from physcap_drake.tasks import object_library
from physcap_drake.tasks.object_library import LibraryError, choose_model, visuals
from physcap_drake.tasks.task_instance import model_url


@pytest.fixture
def cache(tmp_path, monkeypatch):
    monkeypatch.setenv(object_library.CACHE_VARIABLE, str(tmp_path))
    return tmp_path


def test_the_shipped_models_are_chosen_where_they_fit(cache):
    assert choose_model("can", "red", straw=True).model == "objects/can_red_open"
    assert choose_model("lidded_cup", "white").model == "objects/libero_cup_white_plain"
    assert choose_model("paper_cup", size="large").model == "objects/paper_cup_large"
    assert choose_model("avocado", "green", stiffness_level=1).model == \
        "objects/avocado_green_ripe"
    cube = choose_model("box", "blue", dimensions_m=[0.05, 0.05, 0.05])
    assert (cube.model, cube.category) == ("scene/cube_5cm", "cube")
    assert not list(cache.rglob("*.sdf"))  # nothing generated for them


@pytest.mark.parametrize(("family", "options", "category", "height"), [
    ("box", {"color": "red", "dimensions_m": [0.04, 0.05, 0.06]}, "box", 0.06),
    ("ball", {"color": "orange", "dimensions_m": [0.03], "stiffness_level": 2}, "ball", 0.06),
    ("ball", {"color": "orange", "dimensions_m": [0.03], "stiffness_level": 5}, "ball", 0.06),
    ("avocado", {"color": "dark", "stiffness_level": 3}, "avocado", 0.072),
])
def test_models_made_by_data_are_valid_bodies_on_the_table(cache, family, options, category,
                                                           height):
    choice = choose_model(family, **options)
    assert choice.model.startswith(str(cache)) and choice.category == category
    plant, scene_graph = _load(model_url(choice.model))
    (body,) = [plant.get_body(i) for i in plant.GetBodyIndices(
        plant.GetModelInstanceByName(choice.model.rsplit("/", 1)[-1]))]
    assert body.default_spatial_inertia().IsPhysicallyValid()
    lows, highs = zip(*(_z_extent(shape, X) for _, shape, X in _geometries(
        plant, scene_graph, body, Role.kProximity)), strict=True)
    assert min(lows) == pytest.approx(0.0, abs=1e-3)
    assert max(highs) == pytest.approx(height, abs=1e-3)
    assert choose_model(family, **options) == choice  # the cached file is reused


def test_stiffness_does_not_show_in_the_looks(cache):
    soft, firm = (choose_model("ball", "orange", dimensions_m=[0.03], stiffness_level=level)
                  for level in (1, 4))
    assert soft.model != firm.model and visuals(soft.model) == visuals(firm.model)
    assert "<diffuse>0.95 0.50 0.10 1</diffuse>" in visuals(soft.model)[0]  # orange


@pytest.mark.parametrize(("family", "options", "key"), [
    ("teapot", {}, "family"),
    ("can", {"color": "tan"}, "color"),
    ("box", {"color": "red", "dimensions_m": [0.05, 0.05]}, "dimensions_m"),
    ("box", {"color": "red", "dimensions_m": [0.05, 0.05, 0.09]}, "dimensions_m"),
    ("ball", {"color": "red", "dimensions_m": [0.05], "stiffness_level": 1}, "dimensions_m"),
    ("avocado", {"color": "dark", "stiffness_level": 5}, "hidden.stiffness_level"),
    ("paper_cup", {"size": "medium"}, "size"),
    ("ball", {"color": "red", "straw": True, "stiffness_level": 1}, "straw"),
])
def test_what_a_family_cannot_make_is_named(cache, family, options, key):
    with pytest.raises(LibraryError) as refused:
        choose_model(family, **options)
    assert refused.value.key == key
