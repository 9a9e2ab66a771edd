"""A finished episode, its diagram and its systems are freed, not kept until the process ends.

pydrake keeps an abstract output port's calculation and a cache entry's calc in C++, where
Python's garbage collector cannot see that they refer back to their system
(physcap_drake.weak_method). These tests check the mechanism through a system's ports and
read the package's source for every such declaration. They also run one episode and check
that nothing of it is left once its run is dropped.
"""

from __future__ import annotations

import ast
import gc
import weakref
from pathlib import Path

import pytest
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import DiagramBuilder, LeafSystem, ValueProducer

import physcap_drake
from physcap_drake.app.agent_episode import run_agent_episode
from physcap_drake.weak_method import weak_method

ROOT = Path(physcap_drake.__file__).parent


class Counter(LeafSystem):
    """An abstract output (its time, doubled through a cache entry) whose calculations are
    bound methods, given to Drake directly or through weak_method; also a vector output and
    a periodic event as bound methods (pydrake frees those itself)."""

    def __init__(self, weak: bool):
        super().__init__()
        wrap = weak_method if weak else (lambda method: method)
        doubled = self.DeclareCacheEntry(
            "doubled", ValueProducer(allocate=lambda: AbstractValue.Make(0.0),
                                     calc=wrap(self._double)), {self.time_ticket()})
        self._doubled = doubled.cache_index()  # the entry itself would keep self alive
        self.DeclareAbstractOutputPort("doubled", lambda: AbstractValue.Make(0.0),
                                       wrap(self._output), {doubled.ticket()})
        self.DeclareVectorOutputPort("time", 1, self._time)
        self.DeclarePeriodicPublishEvent(0.1, 0.0, self._tick)

    def _double(self, context, value):
        value.set_value(2.0 * context.get_time())

    def _output(self, context, output):
        output.set_value(self.get_cache_entry(self._doubled).Eval(context))

    def _time(self, context, output):
        output.SetAtIndex(0, context.get_time())

    def _tick(self, context):
        pass


def built(weak: bool):
    builder = DiagramBuilder()
    system = builder.AddSystem(Counter(weak))
    builder.ExportOutput(system.GetOutputPort("doubled"), "doubled")
    return builder.Build(), weakref.ref(system)


def test_a_system_whose_abstract_output_and_cache_use_weak_method_is_freed_with_its_diagram():
    diagram, system = built(weak=True)
    gc.collect()
    context = diagram.CreateDefaultContext()
    context.SetTime(1.25)
    # Only the diagram holds the system now, and its ports still work.
    assert system() is not None
    assert diagram.GetOutputPort("doubled").Eval(context) == pytest.approx(2.5)
    del diagram, context
    gc.collect()
    assert system() is None


def test_with_bound_methods_the_same_system_outlives_its_diagram():
    """Why weak_method exists (Drake 1.58). If this starts failing, pydrake frees such
    systems itself and weak_method can go."""
    diagram, system = built(weak=False)
    del diagram
    gc.collect()
    assert system() is not None


def test_weak_method_takes_only_bound_methods_and_names_the_method_once_its_object_is_gone():
    with pytest.raises(TypeError, match="needs a bound method"):
        weak_method(lambda context, output: None)

    class Holder:
        def value(self, x):
            return 2 * x

    holder = Holder()
    call = weak_method(holder.value)
    assert call(21) == 42
    del holder
    gc.collect()
    with pytest.raises(RuntimeError, match="Holder.value was called after its system was "
                                           "destroyed"):
        call(1)


# --- the package's declarations ---------------------------------------------------------------

#: Declarations whose calculation Drake keeps in C++: call name -> where the calc is
#: (index of the positional argument, keyword).
CALCS = {"DeclareAbstractOutputPort": (2, "calc"), "ValueProducer": (1, "calc")}


def _refers_to_self_outside_weak_method(node: ast.AST) -> bool:
    if (isinstance(node, ast.Call) and isinstance(node.func, ast.Name)
            and node.func.id == "weak_method"):
        return False
    if isinstance(node, ast.Name) and node.id == "self":
        return True
    return any(_refers_to_self_outside_weak_method(child) for child in ast.iter_child_nodes(node))


def _offences(source: str, file: str) -> list[str]:
    found = []
    for node in ast.walk(ast.parse(source)):
        if (isinstance(node, ast.Assign) and isinstance(node.value, ast.Call)
                and getattr(node.value.func, "attr", "") == "DeclareCacheEntry"
                and any(_refers_to_self_outside_weak_method(t) for t in node.targets)):
            found.append(f"{file}:{node.lineno}: a CacheEntry kept on self keeps its system "
                         "alive; keep its cache_index()")
        if not isinstance(node, ast.Call):
            continue
        name = getattr(node.func, "attr", getattr(node.func, "id", ""))
        if name not in CALCS:
            continue
        index, keyword = CALCS[name]
        arguments = list(node.args[:index + 1])[index:] + [
            k.value for k in node.keywords if k.arg == keyword]
        # The allocator is kept in C++ too: a lambda over self would do the same harm.
        arguments += [a for a in node.args[:index] if isinstance(a, ast.Lambda)]
        arguments += [k.value for k in node.keywords
                      if k.arg == "allocate" and isinstance(k.value, ast.Lambda)]
        for argument in arguments:
            if _refers_to_self_outside_weak_method(argument):
                found.append(f"{file}:{node.lineno}: {name} is given "
                             f"{ast.unparse(argument)!r}; pass weak_method(self._calc)")
    return found


def test_every_abstract_output_and_cache_entry_of_the_package_keeps_no_strong_self():
    offences = []
    for path in sorted(ROOT.rglob("*.py")):
        offences += _offences(path.read_text(), str(path.relative_to(ROOT)))
    assert offences == []


def test_the_source_check_finds_bound_methods_closures_over_self_and_kept_entries():
    source = """
class S:
    def __init__(self):
        self.DeclareAbstractOutputPort("a", alloc, self._calc)
        self.DeclareAbstractOutputPort("b", alloc, lambda c, o: o.set_value(self.x))
        self.DeclareAbstractOutputPort("c", lambda: self.model, weak_method(self._calc))
        self.DeclareCacheEntry("d", ValueProducer(allocate=alloc, calc=self._calc), set())
        self.DeclareAbstractOutputPort("e", alloc, weak_method(self._calc))
        self.DeclareAbstractOutputPort("f", alloc, partial(weak_method(self._copy), port))
        self._entry = self.DeclareCacheEntry("g", ValueProducer(alloc, calc), set())
        index = self.DeclareCacheEntry("h", ValueProducer(alloc, calc), set()).cache_index()
"""
    offences = _offences(source, "s.py")
    assert sorted(int(line.split(":")[1]) for line in offences) == [4, 5, 6, 7, 10]


# --- an episode -----------------------------------------------------------------------------


@pytest.mark.episode
def test_a_finished_episode_is_freed_once_its_run_is_dropped():
    """Each episode used to stay in its process for good, about 0.1 GB each (the evaluation
    replaced its workers every 4 episodes for it)."""
    run = run_agent_episode("find_blue_cube", 0, agent="physcap", llm="reference",
                            robot_time_limit=1.0)
    assert run.outcome.robot_time_s > 0.0
    episode, diagram = weakref.ref(run.episode), weakref.ref(run.episode.robot.diagram)
    agent = weakref.ref(run.episode.robot.agent)
    del run
    gc.collect()
    assert (episode(), diagram(), agent()) == (None, None, None)
