"""The knowledge lines prompts show: value, unit and meaning; diagnostics kept out; the
robot time and the task's budget."""

import dataclasses as dc

from physcap_drake.knowledge import KnowledgeEntry, SceneKnowledge, time_line


def test_a_measurement_line_carries_value_unit_and_meaning_not_the_diagnostics():
    entry = KnowledgeEntry("dark avocado 1", "stiffness", 2, "level", True, "soft", 31.0,
                           detail="level 2 (soft); rejected as a passing spike: effort 0.04")
    assert entry.describe() == "dark avocado 1: stiffness = 2 level (soft)"
    assert "passing spike" in dc.asdict(entry)["detail"]  # what the transcript records


def test_a_failed_measurement_keeps_its_reason():
    entry = KnowledgeEntry("can 2", "mass", float("nan"), "kg", False, "the object slipped")
    assert entry.describe() == ('failed mass measurement of the object called "can 2" '
                                "(the object slipped)")


def test_a_lift_is_a_sentence():
    knowledge = SceneKnowledge()
    knowledge.add(KnowledgeEntry("large cup 1", "lift", 0, "objects", True,
                                 sentence="lifted large cup 1: nothing under it; set it back"))
    assert knowledge.as_text() == "- lifted large cup 1: nothing under it; set it back"


def test_time_line_with_and_without_budget():
    assert time_line(34.4) == "- robot time used: 34 s"
    assert time_line(34.4, 200.0) == ("- robot time used: 34 s of the task's 200 s budget "
                                      "(166 s left)")
    assert time_line(230.0, 200.0).endswith("(0 s left)")
    assert SceneKnowledge().as_text(12.0, 200.0).splitlines() == [
        "(nothing measured yet)", time_line(12.0, 200.0)]
