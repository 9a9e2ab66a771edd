"""What generated code can reach: never a raw module, nor objects of operator, functools, sys,
os or ctypes.

First the route of issue 43 (an AttributeError's `.obj` handing out the raw numpy module)
and its variants, run as real code blocks; then the views and the attribute guard in this
process; then a bounded walk over everything allowed code can reach, reading attributes
exactly as `obj.name` in generated code does (through `views.guarded_attribute`), and
entering the values and the errors each read gives, the items of containers, the results of
the calls a task makes and the errors bad calls raise.
"""

from __future__ import annotations

import math
from collections import deque
from types import ModuleType

import numpy as np
import pytest
from test_sandbox import FakeRobot, no_leftover_processes, run  # noqa: F401 - fixture

from physcap_drake.agent.sandbox import policy, restricted, views

ROUTE = (
    "import numpy as np\nimport math\n"
    "try:\n    {target}.no_such_attribute\n"
    "except AttributeError as error:\n    raw = error.obj\n"
    "os = raw.ma.core.operator.attrgetter('lib._npyio_impl.os')(raw)\n"
    "print('escaped', os.getpid())\n"
)
TARGETS = ["np", "np.linalg", "np.random", "math", "np.zeros(2)", "np.random.default_rng(0)"]


@pytest.fixture
def robot() -> FakeRobot:
    return FakeRobot()


@pytest.mark.parametrize("target", TARGETS)
@pytest.mark.parametrize("static_check", [True, False], ids=["checked", "runtime_only"])
def test_the_route_of_issue_43_ends_with_an_error(robot, target, static_check):
    outcome = run(ROUTE.format(target=target), robot, _skip_ast_check=not static_check)
    assert outcome.kind == "exception", outcome
    assert "escaped" not in outcome.stdout
    assert "AttributeError at line 6" in outcome.error and ".obj" in outcome.error


@pytest.mark.parametrize("code", [
    "x = np.zeros(2)\nx.no_such += 1\n",                        # augmented read
    "import numpy.linalg as la\nla.inv.no_such\n",               # attribute of a function
    "np.linalg.inv(np.zeros((2, 2)))\n",                         # an error from a raw call
])
def test_errors_the_code_catches_show_only_their_args(robot, code):
    probe = ("try:\n" + "".join(f"    {line}\n" for line in code.splitlines())
             + "except Exception as error:\n    print('args', error.args)\n"
             "    print('obj', error.obj)\n")
    outcome = run(probe, robot)
    assert outcome.kind == "exception", outcome
    assert "args (" in outcome.stdout
    assert "an error shows only its args" in outcome.error


def test_the_codes_own_classes_and_errors_keep_their_attributes(robot):
    code = ("class Reading(Exception):\n    pass\n"
            "class Box:\n    pass\n"
            "box = Box()\nbox.count = 1\nbox.count += 2\n"
            "try:\n    error = Reading('bad')\n    error.value = box.count\n    raise error\n"
            "except Reading as caught:\n    print(caught.value, caught.args)\n"
            "print(np.pi > 3, math.tau > 6, np.zeros(3).shape)\n")
    outcome = run(code, robot)
    assert outcome.ok, outcome.error
    assert outcome.stdout == "3 ('bad',)\nTrue True (3,)\n"


def test_a_view_raises_its_errors_afresh():
    view = views.wrap_module(np)
    with pytest.raises(AttributeError) as caught:
        view.no_such_attribute  # noqa: B018 - the lookup is the test
    error = caught.value
    assert error.obj is view  # Python sets it to the object looked up on: the view
    assert error.__context__ is None and error.__cause__ is None
    assert "no_such_attribute" in str(error)
    for obj in (np.zeros(2), np.random.default_rng(0), math):  # any object's read, guarded
        with pytest.raises(AttributeError) as caught:
            views.guarded_attribute(obj, "no_such_attribute")
        error = caught.value
        assert error.obj is None and error.name is None
        assert error.__context__ is None and error.__cause__ is None


def test_the_guard_refuses_modules_and_raw_module_objects():
    import functools
    import operator
    with pytest.raises(AttributeError, match="module os"):
        views.mediated(__import__("os"), "x")
    assert isinstance(views.mediated(np.linalg, "x"), views.SandboxedModule)
    for raw in (operator.attrgetter("a"), functools.partial(abs), operator.getitem,
                functools.reduce, getattr, eval):
        with pytest.raises(AttributeError, match="not available in the sandbox"):
            views.mediated(raw, "x")
    for plain in (abs, len, np.zeros(2), np.linalg.inv, 1.5, "text", ValueError("v")):
        assert views.mediated(plain, "x") is plain


def test_an_exception_from_a_raw_class_becomes_a_builtin_one():
    class Strange(KeyError):
        pass

    fresh = views.fresh_error(Strange("k"))
    assert type(fresh) is KeyError and fresh.args == ("'k'",)
    odd = views.fresh_error(np.linalg.LinAlgError("singular"))
    assert type(odd) is ValueError or type(odd) is RuntimeError
    assert "singular" in str(odd)


# -- the walk ----------------------------------------------------------------------------

MAX_NODES = 200_000  # depth 5 reaches about 76,000 (depth 7: 720,000, none raw)
MAX_DEPTH = 5
MAX_ITEMS = 64


def _call_results() -> list[object]:
    """Values the calls of ordinary code return, and errors bad calls raise."""
    results: list[object] = [
        np.zeros(3), np.array(["a"]), np.array([1], dtype=object), np.arange(4).flat,
        np.random.default_rng(0), np.random.RandomState(0), np.polynomial.Polynomial([1, 2]),
        np.errstate(), np.vectorize(abs), np.nditer(np.zeros(2)), np.finfo(float),
        np.iinfo(int), np.dtype(float), np.linalg.svd(np.eye(2)), np.linalg.eigh(np.eye(2)),
        np.unique([1, 1], return_counts=True), np.histogram([1, 2]), np.mgrid[0:2],
        np.fft.rfft([1.0, 0.0]), np.polynomial.Polynomial.fit([0, 1, 2], [1, 2, 5], 2),
        np.random.default_rng(0).bit_generator,
    ]
    for bad in (lambda: np.linalg.inv(np.zeros((2, 2))), lambda: np.zeros(3).reshape(2),
                lambda: np.ones(3)[5], lambda: math.sqrt(-1), lambda: np.array([1]) @ "x",
                lambda: np.random.default_rng("x"), lambda: np.polynomial.Polynomial("x"),
                lambda: int("x"), lambda: {}["k"], lambda: np.add.reduce(np.zeros(2), 7)):
        try:
            bad()
        except Exception as error:  # noqa: BLE001 - the errors are what the walk enters
            results.append(error)
    return results


def _roots() -> list[object]:
    table = restricted.make_builtins(print)
    roots = [value for name, value in table.items() if not name.startswith("_")]
    roots += [views.wrap_module(__import__(name, fromlist=["x"]))
              for name in sorted(policy.ALLOWED_MODULES)]
    return roots + _call_results()


def _names(obj: object) -> list[str]:
    try:
        return [name for name in dir(obj) if policy.attribute_problem(name) is None]
    except Exception:  # noqa: BLE001 - an object without a usable dir has no names to walk
        return []


def _items(obj: object) -> list[object]:
    if isinstance(obj, dict) and len(obj) <= MAX_ITEMS:
        return list(obj.values())
    if isinstance(obj, list | tuple | set | frozenset) and len(obj) <= MAX_ITEMS:
        return list(obj)
    return []


def _walk() -> tuple[list[tuple[str, object]], int]:
    """(path, value) of every object reached, and how many reads were refused."""
    seen: set[int] = set()
    keep: list[object] = []  # keeps every reached object alive, so ids stay unique
    found: list[tuple[str, object]] = []
    refused = 0
    frontier = deque((f"root{index}", root, 0) for index, root in enumerate(_roots()))
    while frontier and len(found) < MAX_NODES:
        path, obj, depth = frontier.popleft()
        if id(obj) in seen or obj is None:
            continue
        seen.add(id(obj))
        keep.append(obj)
        found.append((path, obj))
        if depth >= MAX_DEPTH or isinstance(obj, str | bytes | int | float | complex | bool):
            continue
        for index, item in enumerate(_items(obj)):
            frontier.append((f"{path}[{index}]", item, depth + 1))
        for name in _names(obj):
            try:
                value = views.guarded_attribute(obj, name)
            except Exception as error:  # noqa: BLE001 - the code could catch it: walk it too
                refused += 1
                frontier.append((f"{path}.{name}!{type(error).__name__}", error, depth + 1))
                continue
            frontier.append((f"{path}.{name}", value, depth + 1))
    return found, refused


#: Builtins the static check forbids by name that reach nothing when held (numpy lists
#: memoryview among its scalar types).
HARMLESS_BUILTINS = frozenset({"memoryview"})


def _raw(value: object) -> str | None:
    if isinstance(value, ModuleType):
        return f"module {value.__name__}"
    if isinstance(value, dict) and "__builtins__" in value:
        return "a module's namespace"
    home = views.home_module(value).partition(".")[0]
    if home in views.RAW_MODULES:
        return f"an object of {home}"
    name = getattr(value, "__name__", "")
    if callable(value) and home == "builtins" and name in policy.FORBIDDEN_NAMES \
            and name not in HARMLESS_BUILTINS:
        return f"the builtin {value.__name__}"
    return None


def test_nothing_allowed_code_can_reach_is_a_raw_module_or_its_objects():
    found, refused = _walk()
    assert len(found) > 5_000, "the walk reached too little to mean anything"
    assert refused > 100, "the walk met no refusal: is the guard in the way at all?"
    raw = [(path, what) for path, value in found if (what := _raw(value))]
    assert raw == [], raw[:10]
    reached = {id(value) for _, value in found}
    for expected in (np.linalg.inv, np.random.default_rng, np.ndarray.sum, math.hypot):
        assert id(expected) in reached, expected
    print(f"{len(found)} objects reached, {refused} reads refused")
