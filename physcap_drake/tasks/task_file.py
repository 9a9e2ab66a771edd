"""The task file: one evaluation task as data (YAML read with Drake's `yaml_load_typed`).

Every field has a default and a comment; docs/task_files.md teaches the format and
`tasks/files/*.yaml` are the shipped tasks. `load_task_file` raises ScenarioError naming the
file, the key path and the bad value.
"""

# No `from __future__ import annotations`: yaml_load_typed reads the field types at run time.
import dataclasses as dc
from pathlib import Path

from pydrake.common.yaml import yaml_load_typed

from physcap_drake.scenario_errors import ScenarioError, locate_yaml_error
from physcap_drake.tasks.task_file_checks import check_task_file


@dc.dataclass
class Hidden:
    """What only an interaction reveals; never shown to agents."""

    # Mass, kg: [] keeps the model's own, [m] one value, [low, high] drawn by the seed.
    mass_kg: list[float] = dc.field(default_factory=list)
    # Stiffness level as the squeeze probe names it, 1 (ultra-soft) .. 5 (rigid); 0: not
    # stated. A compliant family (avocado, ball) takes its body's modulus from it.
    stiffness_level: int = 0
    # What the object holds, in words ("" for not stated), e.g. "nothing" or "a weight".
    contents: str = ""
    # Named yes/no properties the checks and tests read, e.g. {ripe: true}.
    flags: dict[str, bool] = dc.field(default_factory=dict)


@dc.dataclass
class ObjectEntry:
    """One kind of object, from the object library (tasks/object_library.py)."""

    # How the prompt and the camera name it; objects sharing a name are numbered 1, 2, ...
    # in layout order (left to right in the camera's image).
    name: str = ""
    # Model instance name in the simulation; "{color}" and "{slot}" (its place in the
    # layout, from 0) are filled in.
    body: str = ""
    # How many objects of this kind.
    count: int = 1
    # Library family: can, lidded_cup, paper_cup, avocado, box or ball.
    family: str = ""
    # Visible colour ("" takes the family's own colour where it has one).
    color: str = ""
    # Size class as the camera names it ("large", "small"; "" for none).
    size: str = ""
    # Free geometry, m: a box's [x, y, z]; a ball's [radius]; [] the family's default.
    dimensions_m: list[float] = dc.field(default_factory=list)
    # A straw in its lid or opening (cans, lidded cups).
    straw: bool = False
    # Its hidden properties (the answer's are laid over them, see Answer.hidden).
    hidden: Hidden = dc.field(default_factory=Hidden)


@dc.dataclass
class Layout:
    """Where a group's objects stand (world frame, m; +y is left in the camera's image)."""

    # "row" (one x, a y per slot), "grid" (every x with every y, row by row), "places"
    # (explicit [x, y] each), "scatter" (drawn in `region`, `min_spacing_m` apart) or
    # "under_answer" (at the answer's spot, hidden under it).
    kind: str = "row"
    # row: [x]; grid: the xs.
    x: list[float] = dc.field(default_factory=list)
    # row and grid: the ys, left to right.
    y: list[float] = dc.field(default_factory=list)
    # places: [[x, y], ...].
    places: list[list[float]] = dc.field(default_factory=list)
    # scatter: [[x_min, y_min], [x_max, y_max]], and the least distance between two objects.
    region: list[list[float]] = dc.field(default_factory=list)
    min_spacing_m: float = 0.0
    # Each slot moves by up to this much in x and in y (uniform), m.
    jitter_m: float = 0.0
    # Each object turns by up to this much about z (uniform), rad; 0: no turn.
    yaw_jitter_rad: float = 0.0
    # The seed permutes the group's objects over the slots.
    shuffle: bool = False


@dc.dataclass
class Group:
    """Objects laid out together."""

    layout: Layout = dc.field(default_factory=Layout)
    # The seed gives this many of the group's objects a straw, the others none (0: as listed).
    draw_straws: int = 0
    objects: list[ObjectEntry] = dc.field(default_factory=list)


@dc.dataclass
class Among:
    """Which objects may be the answer: those whose visible attributes match every field
    given here (the visually plausible ones)."""

    category: str = ""
    color: str = ""
    size: str = ""
    # true or false: only objects with (without) a straw; unset: either.
    straw: bool | None = None


@dc.dataclass
class Answer:
    """How the seed draws the answer (uniformly among the plausible objects, in the order
    the file lists them, copies of one entry left to right) and what makes it the answer."""

    among: Among = dc.field(default_factory=Among)
    # The answer's hidden properties, laid over those of its entry.
    hidden: Hidden = dc.field(default_factory=Hidden)


@dc.dataclass
class Destination:
    """The container the answer goes to (or lifted objects are put in)."""

    # As the camera names it.
    name: str = "wooden tray"
    # Its body in the scenario.
    body: str = "tray"
    # Centre of its floor's underside, world frame, m.
    bottom: list[float] = dc.field(default_factory=lambda: [0.30, -0.27, 0.0])
    # Floor thickness and inner half-size (x, y) inside the walls, m.
    floor_m: float = 0.008
    inner_half_m: list[float] = dc.field(default_factory=lambda: [0.144, 0.104])


@dc.dataclass
class Success:
    """The success check, from a small vocabulary (all those set must hold)."""

    # The answer in the destination, and no other object there.
    answer_alone_in_destination: bool = False
    # ... and standing upright in it (tilt <= 10°).
    answer_upright: bool = False
    # Every object but the answer ends within 2 cm of where it stood (or is put back).
    others_stay: bool = False
    # Objects of this category must not be knocked over (> 30°), and once moved must stand
    # upright on the table or in the destination ("" for none).
    upright: str = ""
    # Every object of this category must be in the camera's view ("" for none).
    all_visible: str = ""
    # Robot time allowed, s (0: no limit); the prompt should say it.
    time_limit_s: float = 0.0


@dc.dataclass
class TaskFile:
    """One task: its instruction, scene, hidden answer and success check."""

    # The task's name (runs and tables show it); "" takes the file's stem.
    name: str = ""
    # The scenario file it extends (in stations/).
    scenario: str = ""
    # What the agent is told.
    instruction: str = ""
    # The task's own number in its random streams (layout: (seed, stream); answer:
    # (seed, stream, 101); drawn masses: (seed, stream, 102)).
    stream: int = 0
    groups: list[Group] = dc.field(default_factory=list)
    answer: Answer = dc.field(default_factory=Answer)
    destination: Destination = dc.field(default_factory=Destination)
    success: Success = dc.field(default_factory=Success)


def load_task_file(path: str | Path) -> TaskFile:
    """Reads and checks a task file. Raises ScenarioError naming the file and key path."""
    label = str(path)
    if not Path(path).is_file():
        raise ScenarioError(filename=label, key_path="", expected="an existing task file",
                            problem="no such file")
    try:
        task = yaml_load_typed(schema=TaskFile, filename=str(path))
    except (RuntimeError, ValueError, TypeError, KeyError, AssertionError) as error:
        located = locate_yaml_error(error, label)
        raise ScenarioError(filename=label, key_path=located.key_path,
                            expected=located.expected.replace("Scenario", "TaskFile"),
                            problem=located.problem) from error
    except Exception as error:  # yaml syntax errors carry their own line and column
        raise ScenarioError(filename=label, key_path="", expected="valid YAML",
                            problem=str(error)) from error
    task.name = task.name or Path(path).stem
    check_task_file(task, label)
    return task
