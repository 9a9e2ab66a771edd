"""Perception's memory across looks: a container keeps its area while objects stand on it,
objects that stayed keep their names and attributes, sizes come from the kind's typical
sizes (not from the neighbours in view)."""

from __future__ import annotations

import dataclasses as dc

import numpy as np
import pytest

from physcap_drake.perception import regions
from physcap_drake.perception.container_memory import ContainerMemory
from physcap_drake.perception.describe import ObjectView
from physcap_drake.perception.object_memory import ObjectMemory
from physcap_drake.perception.shapes import size_word

#: A 0.30 m x 0.22 m tray centred at (0.30, -0.27) as its floor's points show it.
TRAY_LOW, TRAY_HIGH = np.array([0.15, -0.38]), np.array([0.45, -0.16])


def _tray_points(rng, keep=lambda xy: np.ones(len(xy), bool), shift=(0.0, 0.0)):
    xy = rng.uniform(TRAY_LOW, TRAY_HIGH, (4000, 2)) + shift
    return xy[keep(xy)]


def test_a_tray_keeps_its_area_while_cups_hide_most_of_it():
    rng = np.random.default_rng(0)
    memory = ContainerMemory()
    first = memory.area("tray", _tray_points(rng), lambda rectangle: 0.008)
    assert first.mean(axis=0) == pytest.approx([0.30, -0.27], abs=0.003)
    # Two cups on it leave only a strip of floor in view near its left end.
    strip = _tray_points(rng, keep=lambda xy: xy[:, 0] < 0.22)
    assert memory.area("tray", strip, lambda rectangle: 0.008) == pytest.approx(first)
    # The strip's own rectangle is far off: without the kept area the tray would move.
    assert regions.footprint_rectangle(strip).mean(axis=0)[0] < 0.20


def test_a_tray_that_moved_is_measured_anew():
    rng = np.random.default_rng(1)
    memory = ContainerMemory()
    memory.area("tray", _tray_points(rng), lambda rectangle: 0.008)
    # No floor under the kept rectangle any more (2 mm: the table): it moved away.
    moved = memory.area("tray", _tray_points(rng, shift=(0.0, 0.25)), lambda r: 0.002)
    assert moved.mean(axis=0) == pytest.approx([0.30, -0.02], abs=0.003)
    # A floor still under the kept rectangle (5 mm) keeps it.
    rng2 = np.random.default_rng(2)
    memory2 = ContainerMemory()
    kept = memory2.area("tray", _tray_points(rng2), lambda rectangle: 0.008)
    assert memory2.area("tray", _tray_points(rng2, shift=(0.0, 0.25)),
                        lambda r: 0.005) == pytest.approx(kept)


def test_kept_containers_carry_the_top_they_were_measured_with():
    rng = np.random.default_rng(5)
    memory = ContainerMemory()
    memory.area("brown basket", _tray_points(rng), lambda rectangle: 0.004, 0.061)
    # Seen again with a cup in it (its top higher now): the first measure is kept.
    memory.area("brown basket", _tray_points(rng), lambda rectangle: 0.004, 0.09)
    (rectangle, top), = memory.kept()
    assert top == 0.061
    assert rectangle.mean(axis=0) == pytest.approx([0.30, -0.27], abs=0.003)
    # Measured anew (it moved): the new top with the new rectangle.
    memory.area("brown basket", _tray_points(rng, shift=(0.0, 0.25)), lambda r: 0.0, 0.058)
    assert memory.kept()[0][1] == 0.058


def test_a_tray_first_seen_in_part_grows_to_its_whole_area():
    rng = np.random.default_rng(4)
    memory = ContainerMemory()
    part = memory.area("tray", _tray_points(rng, keep=lambda xy: xy[:, 1] < -0.24),
                       lambda rectangle: 0.008)
    assert part.mean(axis=0)[1] == pytest.approx(-0.31, abs=0.005)
    whole = memory.area("tray", _tray_points(rng), lambda rectangle: 0.008)
    assert whole.mean(axis=0) == pytest.approx([0.30, -0.27], abs=0.003)


def _view(category, color, x, y, height=0.1, width=0.075):
    region = regions.Region(np.zeros((2, 2), bool), np.zeros(0, int), np.zeros(0, int),
                            np.zeros((0, 3)), np.zeros(0), column=100 - 200 * y, row=0.0)
    return ObjectView(category, color, False, height, (width, width), np.array([x, y]),
                      np.array([x, y, height / 2]), region)


def test_an_object_that_stayed_keeps_its_name_when_its_outline_looks_different():
    memory = ObjectMemory()
    memory.recognize([_view("cube", "blue", 0.30, 0.25, 0.05, 0.05),
                      _view("cube", "blue", 0.30, 0.10, 0.05, 0.05),
                      _view("cup", "white", 0.44, 0.03)])
    # The cup is lifted away and uncovers a third cube while cube 2, 1 cm from where it
    # was, is judged an unknown object this time.
    names = memory.recognize([_view("cube", "blue", 0.30, 0.25, 0.05, 0.05),
                              _view("object", "blue", 0.30, 0.11, 0.06, 0.05),
                              _view("cube", "blue", 0.44, 0.03, 0.05, 0.05),
                              _view("cup", "white", 0.30, -0.30)])
    assert [(v.name, v.category) for v in names] == [
        ("blue cube 1", "cube"), ("blue cube 2", "cube"), ("blue cube 3", "cube"),
        ("large white cup", "cup")]
    # 3 cm away, of another kind: another object, not cube 2.
    memory = ObjectMemory()
    memory.recognize([_view("cube", "blue", 0.30, 0.10, 0.05, 0.05)])
    names = memory.recognize([_view("object", "blue", 0.30, 0.13, 0.06, 0.05)])
    assert names[0].name == "blue object"
    # First judged of no known kind, then seen as a cup where it stood: a cup from now on.
    memory = ObjectMemory()
    assert memory.recognize([_view("object", "blue", 0.30, 0.01, 0.09, 0.04)])[0].name == (
        "blue object")
    assert memory.recognize([_view("cup", "blue", 0.30, 0.01)])[0].category == "cup"


def test_sizes_are_judged_against_the_kinds_typical_sizes():
    # A large and a small paper cup, and the lidded take-away cup that has no size word.
    assert size_word("cup", 0.100, (0.075, 0.075)) == "large"
    assert size_word("cup", 0.066, (0.043, 0.043)) == "small"
    assert size_word("cup", 0.086, (0.049, 0.049)) == ""
    assert size_word("cube", 0.053, (0.05, 0.05)) == ""
    # "Four cups with lids": one size, whatever the one in view measures.
    assert size_word("cup", 0.066, (0.043, 0.043), ("lidded cup", "basket")) == ""
    assert size_word("cup", 0.066, (0.043, 0.043), ("cup", "blue cube")) == "small"
    # Two large cups and no small one in view: both large (not one of them "small").
    memory = ObjectMemory()
    names = memory.recognize([_view("cup", "white", 0.44, 0.30),
                              _view("cup", "white", 0.44, 0.03, 0.096, 0.072)])
    assert [(v.name, v.size) for v in names] == [("large white cup 1", "large"),
                                                 ("large white cup 2", "large")]
    memory = ObjectMemory()
    names = memory.recognize([_view("cup", "white", 0.44, 0.18, 0.066, 0.043)])
    assert [(v.name, v.size) for v in names] == [("small white cup", "small")]


def _seen_at(name, x, y, category="cup", state="upright", tilt=0.0):
    from physcap_drake.perception.seen_object import SeenObject
    from physcap_drake.perception.visible_objects import VisibleObject

    return SeenObject(VisibleObject(name, category, "white"), np.zeros((2, 2), bool), 0.0,
                      0.0, np.array([x, y, 0.05]), 0.1, np.zeros((3, 2)), None, state, tilt)


def test_the_bench_counts_merges_phantoms_switches_and_stance_errors():
    from physcap_drake.bench.perception_bench import _compare

    truths = {"cup a": (np.array([0.30, 0.10]), 0.0), "cup b": (np.array([0.30, -0.10]), 0.0)}
    first: dict[str, str] = {}
    clean = _compare("t", 0, 0, truths, [_seen_at("cup 1", 0.30, 0.10),
                                         _seen_at("cup 2", 0.30, -0.10)], first, ("cup",))
    assert (clean.merges, clean.phantoms, clean.switches, clean.not_found,
            clean.state_errors) == ([], [], [], [], [])
    # Cup b now stands 2 cm from cup a and is tilted 12 degrees: one seen object covers
    # both (a merge, cup b was 'cup 2'), a shadow becomes an object, and the merged one
    # reads upright.
    truths = {"cup a": (np.array([0.30, 0.10]), 0.0), "cup b": (np.array([0.30, 0.12]), 12.0)}
    later = _compare("t", 0, 1, truths, [_seen_at("cup 1", 0.30, 0.11),
                                         _seen_at("object", 0.2, 0.0, "object", "")],
                     first, ("cup",))
    assert later.merges == ["'cup 1' for cup a, cup b"]
    assert later.phantoms == ["object"]
    assert later.switches == ["cup b: 'cup 2' now 'cup 1'"]
    assert later.state_errors == ["cup b: seen upright 0°, is tilted 12°"]
    # 3.5 cm off: not found rather than matched.
    gone = _compare("t", 0, 2, {"cup a": (np.array([0.30, 0.135]), 0.0)},
                    [_seen_at("cup 1", 0.30, 0.10)], first, ("cup",))
    assert gone.not_found == ["cup a"] and gone.phantoms == ["cup 1"]
    # Two cups standing in the tray seen as part of a basket-like container: a merge, and
    # the container itself (true, with nothing matched to it) is no phantom.
    basket = dc.replace(_seen_at("brown basket", 0.30, -0.27, "basket", ""),
                        area=np.array([[0.2, -0.35], [0.4, -0.35], [0.4, -0.2], [0.2, -0.2]]))
    tray = dc.replace(_seen_at("brown tray", 0.30, 0.30, "tray", ""),
                      area=np.array([[0.2, 0.25], [0.4, 0.25], [0.4, 0.35], [0.2, 0.35]]))
    merged = _compare("t", 0, 3, {"cup a": (np.array([0.30, -0.27]), 0.0)},
                      [basket, tray], {}, ("cup",))
    assert merged.merges == ["'brown basket' for cup a"]
    assert merged.phantoms == [] and merged.not_found == []


def _basket(x, y):
    """A 0.26 m x 0.20 m basket's view, its region's points spread over its floor."""
    xy = np.random.default_rng(0).uniform([x - 0.13, y - 0.10], [x + 0.13, y + 0.10], (400, 2))
    region = regions.Region(np.zeros((2, 2), bool), np.zeros(0, int), np.zeros(0, int),
                            np.column_stack([xy, np.zeros(len(xy))]), np.zeros(len(xy)),
                            column=0.0, row=0.0, container=True)
    return ObjectView("basket", "brown", False, 0.06, (0.2, 0.26), np.array([x, y]),
                      np.array([x, y, 0.03]), region)


def test_a_cup_put_in_a_basket_keeps_its_name_when_the_wall_hides_part_of_it():
    """Set down in the basket, the red cup's lower part is hidden by the wall and it is
    judged a "red object": it is the red cup; outside a container it would be a new object."""
    memory = ObjectMemory()
    first = memory.recognize([_view("cup", "red", 0.35, 0.16, 0.083),
                              _view("cup", "blue", 0.42, 0.02), _basket(0.32, -0.26)])
    names = memory.recognize([_view("object", "red", 0.25, -0.26, 0.09, 0.05),
                              _view("cup", "blue", 0.42, 0.02), _basket(0.32, -0.26)])
    assert names == first and names[0].category == "cup"
    memory = ObjectMemory()
    memory.recognize([_view("cup", "red", 0.35, 0.16, 0.083), _basket(0.32, -0.26)])
    names = memory.recognize([_view("object", "red", 0.25, 0.05, 0.09, 0.05),
                              _basket(0.32, -0.26)])
    assert names[0].name == "red object" and names[0].category == "object"


def test_an_object_the_robot_set_down_keeps_its_name_and_attributes_there():
    """The robot sets the red cup down in the basket and says so: the view there is the red
    cup though the basket's colour bled into it ("brown object", lower than it stood);
    3.9 cm off it still is, 4.1 cm off (with no other rule pairing them) it is not."""
    def after_set_down(x):
        memory = ObjectMemory()
        memory.recognize([_view("cup", "red", 0.35, 0.16, 0.083),
                          _view("cup", "blue", 0.42, 0.02), _basket(0.32, -0.26)])
        memory.set_down("large red cup", (0.26, -0.26))
        return memory, memory.recognize([_view("object", "brown", x, -0.26, 0.045, 0.05),
                                         _view("cup", "blue", 0.42, 0.02),
                                         _basket(0.32, -0.26)])

    memory, names = after_set_down(0.26 + 0.039)
    assert [(v.name, v.category, v.color) for v in names] == [
        ("large red cup", "cup", "red"), ("large blue cup", "cup", "blue"),
        ("brown basket", "basket", "brown")]
    # Still there on the next look (the colour still bleeds in): still the red cup.
    again = memory.recognize([_view("object", "brown", 0.27, -0.26, 0.045, 0.05),
                              _basket(0.32, -0.26)])
    assert again[0].name == "large red cup"
    _, names = after_set_down(0.26 + 0.041)
    assert names[0].name == "brown object"
    # The blue cup is not taken for the red cup set down near it; the basket not for a cup.
    memory = ObjectMemory()
    memory.recognize([_view("cup", "red", 0.35, 0.16, 0.083), _view("cup", "blue", 0.42, 0.02),
                      _basket(0.32, -0.26)])
    memory.set_down("large red cup", (0.32, -0.25))
    names = memory.recognize([_view("cup", "blue", 0.42, 0.02), _basket(0.32, -0.26)])
    assert [v.name for v in names] == ["large blue cup", "brown basket"]


def test_a_set_down_object_seen_elsewhere_later_is_no_longer_pinned_there():
    memory = ObjectMemory()
    memory.recognize([_view("cup", "red", 0.35, 0.16, 0.083), _view("cup", "blue", 0.42, 0.02)])
    memory.set_down("large red cup", (0.20, -0.20))
    # Knocked 10 cm away and seen as a red cup there: paired by kind and colour, and the
    # spot where it was set down is forgotten; a red object appearing there is new.
    assert memory.recognize([_view("cup", "red", 0.30, -0.20, 0.083)])[0].name == (
        "large red cup")
    assert memory.recognize([_view("object", "red", 0.20, -0.20, 0.05, 0.05),
                             _view("cup", "red", 0.30, -0.20, 0.083)])[0].name == "red object"


def test_set_down_refuses_an_unknown_name_and_a_bad_place():
    memory = ObjectMemory()
    memory.recognize([_view("cup", "red", 0.35, 0.16, 0.083)])
    with pytest.raises(ValueError, match="no object named 'red can' was seen; known: "
                                         "large red cup"):
        memory.set_down("red can", (0.2, 0.1))
    with pytest.raises(ValueError, match="two finite numbers"):
        memory.set_down("large red cup", (0.2, float("nan")))
    with pytest.raises(ValueError, match="two finite numbers"):
        memory.set_down("large red cup", (0.2, 0.1, 0.05))
