"""Which object in the latest view the reference reasoner means by a name from an earlier one.

Design notes: docs/design/agent.md.
"""

from __future__ import annotations

from physcap_drake.agent.llm.base import LLMError
from physcap_drake.agent.reference.task_reading import CATEGORIES, DESTINATIONS


class ObjectNotInView(LLMError):
    """The reasoner cannot tell which object in the latest view an earlier name stands for
    (an LLMError: the model cannot answer, and the episode ends with the reason)."""


def current_name(name: str, context: dict, subject: str) -> str:
    """The name, in the context's latest objects list, of the object the reasoner knew as
    `name` (a `subject`, e.g. "avocado"); `name` itself while it is in view. Raises
    ObjectNotInView when no object, or more than one, can be it."""
    in_view = {o["name"]: o for o in context["objects_in_view"]}
    if name in in_view:
        return name
    listed = ", ".join(f"'{n}'" for n in in_view) or "none"
    successors = _successors(name, context["history"])
    if successors is None:
        raise ObjectNotInView(
            f"the '{name}' is not among the objects in view ({listed}), and no code block "
            "so far saw it go out of view, so the reference coder cannot tell which object "
            "it is now")
    fitting = [n for n in successors if n in in_view and _fits(in_view[n], subject)]
    if len(fitting) == 1:
        return fitting[0]
    came = ", ".join(f"'{n}'" for n in successors) or "nothing"
    if not fitting:
        raise ObjectNotInView(
            f"the '{name}' went out of view and no {subject} (or object of unknown kind) "
            f"that came into view in its place is in view now (came into view: {came}; in "
            f"view: {listed}), so the reference coder cannot tell which object it is now")
    raise ObjectNotInView(
        f"the '{name}' went out of view and {len(fitting)} objects that came into view in "
        f"its place could be it ({', '.join(repr(n) for n in fitting)}), so the reference "
        "coder cannot tell which one it is now")


def _successors(name: str, history: list[dict]) -> list[str] | None:
    """The names the object known as `name` may have now, following it through the steps
    (oldest first): None if no step saw it go out of view."""
    names = [name]
    moved = False
    for step in history:
        gone = [n for n in names if n in step["disappeared"]]
        if gone:
            moved = True
            names = [n for n in names if n not in gone]
            names += [n for n in step["appeared"] if n not in names]
    return names if moved else None


def _fits(obj: dict, subject: str) -> bool:
    """Whether an object in view looks like it could be a `subject` seen anew: one, or of a
    kind perception did not name (neither a task kind nor a destination)."""
    category = obj["category"]
    return category == subject or category not in (*CATEGORIES, *DESTINATIONS)
