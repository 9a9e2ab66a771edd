"""The scenario: everything needed to build and run a station, in one typed YAML file.

A scenario file (see `stations/*.yaml`) is loaded with Drake's `yaml_load_typed` into the
`Scenario` dataclass tree below; every field has a default, so a file only says what differs.
Loading also checks values that parse but cannot work (out-of-range numbers, missing model
files, a missing camera) and reports them as a `ScenarioError` naming the file, the key path
and what was expected.
"""

# No `from __future__ import annotations`: yaml_load_typed reads the field types at run time.
import dataclasses as dc
from pathlib import Path

import numpy as np
from pydrake.common.schema import Transform
from pydrake.common.yaml import yaml_load_typed
from pydrake.geometry import MeshcatParams, RenderEngineGlParams, RenderEngineVtkParams
from pydrake.math import RigidTransform, RollPitchYaw
from pydrake.multibody.parsing import FlattenModelDirectives, ModelDirective, ModelDirectives
from pydrake.multibody.plant import MultibodyPlantConfig
from pydrake.systems.analysis import SimulatorConfig
from pydrake.systems.sensors import CameraConfig
from pydrake.visualization import VisualizationConfig

from physcap_drake.config_checks import ConfigChecker
from physcap_drake.control.skills_config import SkillsConfig
from physcap_drake.physx.physx_config import PhysxConfig
from physcap_drake.physx.probe_calibration import (
    apply_probe_calibration,
    load_probe_calibration,
)
from physcap_drake.resources import make_package_map
from physcap_drake.scenario_errors import ScenarioError, file_label, locate_yaml_error
from physcap_drake.scenario_layers import read_layers
from physcap_drake.station.can_config import PiperCan
from physcap_drake.station.realsense.config import RealSense
from physcap_drake.station.robot_model import arm_joint_limits, make_controller_plant
from physcap_drake.station.sim_config import SimPiper

#: Every station exports the ports of the camera with this name as `camera.rgb` etc.
MAIN_CAMERA = "camera"


def _default_plant_config() -> MultibodyPlantConfig:
    # SAP is required: the gripper's fingers are coupled by a constraint only SAP supports.
    # Hydroelastic with fallback: soft objects that declare hydroelastic properties get
    # compliant hydroelastic contact, everything else rigid point contact (cheap).
    # SAP softens a contact that would be stiffer than the step can resolve ("near rigid"):
    # how much depends on the threshold times the step, and on the masses in contact. With
    # Drake's threshold of 1 at a 4 ms step, 15 N finger pads sank 2.5 mm into each side of
    # a 15 g paper cup and up to 8 mm into an 8 g one, whose grasp then crept until it timed
    # out. 0.3 at 8 ms softens 3.3 times less (pads 1-2 mm into the light cups), still holds
    # a 1 kg block without it turning in the grasp, and takes half the steps.
    return MultibodyPlantConfig(
        time_step=0.008,
        discrete_contact_approximation="sap",
        contact_model="hydroelastic_with_fallback",
        sap_near_rigid_threshold=0.3,
    )


def _default_camera() -> CameraConfig:
    # Like the paper's ZED 2i: above and behind the arm, looking down at the workspace.
    # 640 × 360 is the ZED's 1280 × 720 at half resolution (same field of view, cheaper to
    # render); 70° vertical field of view as the ZED 2i's wide lens.
    camera = CameraConfig(
        name=MAIN_CAMERA,
        width=640,
        height=360,
        focal=CameraConfig.FovDegrees(y=70.0),
        z_near=0.1,
        z_far=5.0,
        fps=15.0,
        rgb=True,
        depth=True,
        label=True,
        renderer_name="vtk",
        renderer_class=RenderEngineVtkParams(backend="EGL"),
    )
    camera.X_PB = Transform(RigidTransform(
        RollPitchYaw(np.radians([-145.2109, 0.0, -90.0])), [-0.30, 0.0, 0.95]))
    return camera


@dc.dataclass
class TaskConfig:
    """Which evaluation task the scenario sets up (see physcap_drake/tasks/)."""

    # Task name: "" (none), "identify_empty_can", "pick_ripe_avocado", ...
    name: str = ""
    # Pin which object carries the hidden property (its name, e.g. "red can"); "" draws it
    # from the random seed among the visually plausible ones. On a rig without a simulated
    # world this is how the perception judge knows which object the task is about.
    answer: str = ""
    # What sees the objects in an episode: "rgbd" (colour and depth alone) or "label" (the
    # simulator's perfect segmenter); "" leaves it to `physcap run --perception` (label).
    perception: str = ""
    # Who decides an episode's success: "simulator" (ground truth), "perception" (the
    # final camera view) or "operator" (asked at the end); "" leaves it to
    # `physcap run --judge` (simulator).
    judge: str = ""


@dc.dataclass
class Scenario:
    """A station and its scene. See `stations/piper_table.yaml` for a commented example."""

    # A scenario file this one overrides, relative to this file's folder: its keys replace
    # the base's, the rest stays (see scenario_layers.py). Empty in a loaded scenario.
    base: str = ""
    # Seed of every random choice in a run (sensor noise, later task layouts).
    random_seed: int = 0
    # Default length of `physcap sim`, s of simulated time.
    simulation_duration: float = 5.0
    # The MultibodyPlant: time step, contact model and solver (Drake's MultibodyPlantConfig).
    plant_config: MultibodyPlantConfig = dc.field(default_factory=_default_plant_config)
    # The models and how they are attached (Drake model directives): the arm, its gripper,
    # the table and the objects.
    directives: list[ModelDirective] = dc.field(default_factory=list)
    # Which station: the simulated arm (!SimPiper) or the real arm over CAN (!PiperCan).
    station: SimPiper | PiperCan = dc.field(default_factory=SimPiper)
    # The evaluation task whose objects the scenario's seed lays out (none by default).
    task: TaskConfig = dc.field(default_factory=TaskConfig)
    # Hidden masses of bodies of the simulated world, kg by scoped body name
    # ("model_instance::body"); a task's layout puts its objects' masses here. The world's
    # owner sets them before the world runs (an episode's clock on the simulated station,
    # the emulated arm's world behind a PiperCan station); agents never see them.
    body_masses: dict[str, float] = dc.field(default_factory=dict)
    # Limits and tolerances of the robot skills (goto_pose, gripper, home).
    skills: SkillsConfig = dc.field(default_factory=SkillsConfig)
    # The physical probes get_mass and get_stiffness.
    physx: PhysxConfig = dc.field(default_factory=PhysxConfig)
    # RGB-D cameras; the one named "camera" is the station's camera. Each entry names its
    # source: a Drake CameraConfig (untagged, or !CameraConfig) is rendered in the simulated
    # scene with perfect depth; !RealSense is a RealSense camera (a live device, a .db3
    # recording, or emulated from the simulated scene: see station/realsense/config.py).
    cameras: list[CameraConfig | RealSense] = dc.field(
        default_factory=lambda: [_default_camera()])
    # What Meshcat shows (Drake's VisualizationConfig).
    visualization: VisualizationConfig = dc.field(default_factory=VisualizationConfig)
    # Meshcat's web server; bound to this machine only unless host is changed.
    meshcat: MeshcatParams = dc.field(default_factory=lambda: MeshcatParams(host="localhost"))
    # Integrator and pacing (Drake's SimulatorConfig); target_realtime_rate 0 runs flat out.
    simulator_config: SimulatorConfig = dc.field(
        default_factory=lambda: SimulatorConfig(target_realtime_rate=0.0))


#: How a `--scenario-text` overlay is named in errors.
TEXT_LABEL = "--scenario-text"


def load_scenario(filename: str | Path, scenario_text: str = "") -> Scenario:
    """Loads and checks a scenario file, read over its `base` (if any) and under
    `scenario_text` (YAML over the file's, as `--scenario-text` gives it). Raises
    ScenarioError naming the file (or --scenario-text) and the key path."""
    label = file_label(filename)
    if not Path(filename).is_file():
        raise ScenarioError(filename=label, key_path="", expected="an existing scenario file",
                            problem="no such file")
    scenario: Scenario = read_layers(Path(filename), label, _read_file)
    if scenario_text:
        scenario = _read(TEXT_LABEL, defaults=scenario, data=scenario_text)
    check_scenario(scenario, label if not scenario_text else f"{label} with {TEXT_LABEL}")
    _apply_emulated_mismatch(scenario)
    return scenario


def load_scenario_text(text: str, *, label: str = "<string>") -> Scenario:
    """Loads and checks a scenario given as YAML text (for tests and generated scenarios)."""
    scenario = _read(label, data=text)
    check_scenario(scenario, label)
    _apply_emulated_mismatch(scenario)
    return scenario


def _apply_emulated_mismatch(scenario: Scenario) -> None:
    """Draws an emulated arm unlike its model where the station asks (`emulated_mismatch`)."""
    if isinstance(scenario.station, PiperCan):
        scenario.station.apply_emulated_mismatch()


def _read_file(label: str, path: Path, defaults: Scenario | None) -> Scenario:
    scenario = _read(label, defaults=defaults, filename=str(path))
    _resolve_camera_files(scenario, path.parent)
    _resolve_probe_calibration(scenario, path.parent)
    return scenario


def _read(label: str, defaults: Scenario | None = None, **source) -> Scenario:
    """One YAML document over `defaults` (or the Scenario defaults); a `base` is refused
    here (only a file's base is followed, by read_layers)."""
    try:
        scenario = yaml_load_typed(schema=Scenario, defaults=defaults, **source)
    except (RuntimeError, ValueError, TypeError, KeyError, AssertionError) as error:
        raise locate_yaml_error(error, label) from error
    except Exception as error:  # yaml syntax errors carry their own line and column
        raise ScenarioError(filename=label, key_path="", expected="valid YAML",
                            problem=str(error)) from error
    if scenario.base and "filename" not in source:
        raise ScenarioError(filename=label, key_path="base", expected="no base in YAML "
                            "given as text (a base is a file's, relative to its folder)",
                            problem=f"got {scenario.base!r}")
    return scenario


def _resolve_camera_files(scenario: Scenario, folder: Path) -> None:
    """Makes the files a RealSense entry names (calibration, recording, record_to) relative
    to the scenario file's folder, as a reader of the file expects."""
    for camera in scenario.cameras:
        if isinstance(camera, RealSense):
            for key in ("calibration", "recording", "record_to"):
                value = getattr(camera, key)
                if value and not Path(value).is_absolute():
                    setattr(camera, key, str(folder / value))


def _resolve_probe_calibration(scenario: Scenario, folder: Path) -> None:
    """Makes `physx.calibration_file` relative to the scenario file's folder and, if the
    file exists, puts its fitted values into the probes' configuration."""
    name = scenario.physx.calibration_file
    if not name:
        return
    path = Path(name) if Path(name).is_absolute() else folder / name
    scenario.physx.calibration_file = str(path)
    if path.is_file():
        apply_probe_calibration(scenario.physx, load_probe_calibration(path))


def check_scenario(scenario: Scenario, filename: str = "<scenario>") -> None:
    """Checks the values of a loaded scenario; raises ScenarioError on the first bad one."""
    at = ConfigChecker(filename)
    at.number("random_seed", scenario.random_seed, minimum=0)
    at.number("simulation_duration", scenario.simulation_duration, minimum=0.0)
    _check_plant_config(scenario.plant_config, at.child("plant_config"))
    scenario.station.check(at.child("station"))
    scenario.skills.check(at.child("skills"))
    scenario.physx.check(at.child("physx"))
    _check_directives(scenario, at)
    _check_body_masses(scenario, at)
    at.child("task").choice("perception", scenario.task.perception, ["", "rgbd", "label"])
    at.child("task").choice("judge", scenario.task.judge,
                            ["", "simulator", "perception", "operator"])
    station = scenario.station
    _check_cameras(scenario.cameras, at, simulated=isinstance(station, SimPiper),
                   world=isinstance(station, SimPiper) or station.emulate)
    if isinstance(station, SimPiper):
        _check_against_robot(scenario, station, at, at.child("station"))
    elif isinstance(station, PiperCan):
        at.child("simulator_config").choice(
            "target_realtime_rate", scenario.simulator_config.target_realtime_rate, [1.0])
        if station.emulate:
            _check_against_robot(scenario, station.emulated, at,
                                 at.child("station").child("emulated"))


def _check_plant_config(config: MultibodyPlantConfig, at: ConfigChecker) -> None:
    at.number("time_step", config.time_step, minimum=0.0, maximum=0.02, open_minimum=True,
              why="the station is a discrete-time plant")
    at.choice("discrete_contact_approximation", config.discrete_contact_approximation,
              ["sap"])
    at.choice("contact_model", config.contact_model,
              ["point", "hydroelastic", "hydroelastic_with_fallback"])


def _check_directives(scenario: Scenario, at: ConfigChecker) -> None:
    package_map = make_package_map()
    for index, directive in enumerate(scenario.directives):
        for kind in ("add_model", "add_directives"):
            item = getattr(directive, kind)
            if item is None:
                continue
            here = at.child("directives").child(index).child(kind)
            try:
                path = Path(package_map.ResolveUrl(item.file))
            except RuntimeError as error:  # unknown package, or no file at that URL
                here.fail("file", "an existing model file", f"{item.file!r}: {error}")
            if not path.is_file():
                here.fail("file", "an existing model file",
                          f"{item.file!r} resolves to {path}, which is not a file")
    flat = FlattenModelDirectives(ModelDirectives(directives=scenario.directives), package_map)
    names = [d.add_model.name for d in flat.directives if d.add_model is not None]
    if isinstance(scenario.station, SimPiper | PiperCan):
        for key in ("arm_model", "gripper_model"):
            wanted = getattr(scenario.station, key)
            if wanted not in names:
                at.child("station").fail(key, f"the name of a model the directives add "
                                         f"(they add {names})", f"got {wanted!r}")
    for index, name in enumerate(scenario.skills.furniture):
        if name not in names:
            at.child("skills").child("furniture").fail(
                index, f"the name of a model the directives add (they add {names})",
                f"got {name!r}")


def _check_body_masses(scenario: Scenario, at: ConfigChecker) -> None:
    """Positive masses, and a world to set them in (their names are checked against the
    world's plant where it is built: `station.body_masses`)."""
    station = scenario.station
    if scenario.body_masses and isinstance(station, PiperCan) and not station.emulate:
        at.fail("body_masses", "none on the real arm (station.emulate: false): there is no "
                "simulated world to weigh", f"got {sorted(scenario.body_masses)}")
    for name, kg in scenario.body_masses.items():
        at.child("body_masses").number(name, kg, minimum=0.0, open_minimum=True,
                                       why="a body's mass, kg")


def _check_joints(at: ConfigChecker, key: str, q: list[float], lower, upper) -> None:
    for i, value in enumerate(q):
        at.child(key).number(i, value, minimum=float(lower[i]), maximum=float(upper[i]),
                             why=f"joint J{i + 1}'s limits, rad")


def _check_against_robot(scenario: Scenario, station: SimPiper, at: ConfigChecker,
                         station_at: ConfigChecker) -> None:
    """Checks the values that only make sense against the robot model the directives add,
    for the simulated arm `station` (the scenario's, or an emulator's) found at `station_at`."""
    plant = make_controller_plant(scenario.directives, station.arm_model, station.gripper_model)
    lower, upper = arm_joint_limits(plant, plant.GetModelInstanceByName(station.arm_model))
    _check_joints(station_at, "initial_arm_position", station.initial_arm_position,
                  lower, upper)
    _check_joints(at.child("skills"), "home_position", scenario.skills.home_position,
                  lower, upper)
    gripper = plant.GetModelInstanceByName(station.gripper_model)
    actuators = [plant.get_joint_actuator(i) for i in plant.GetJointActuatorIndices(gripper)]
    if len(actuators) != 1:
        station_at.fail("gripper_model", "a gripper model with one actuated finger",
                        f"{station.gripper_model!r} has {len(actuators)} actuators")
    stroke = 2.0 * float(actuators[0].joint().position_upper_limits()[0])
    station_at.number("initial_gripper_opening", station.initial_gripper_opening,
                      minimum=0.0, maximum=stroke, why="the gripper's stroke, m")
    max_force = station.gripper_servo.max_force
    station_at.child("gripper_servo").number(
        "max_force", max_force, minimum=0.0, maximum=0.5 * actuators[0].effort_limit(),
        open_minimum=True, why="half the finger actuator's limit: it drives both fingers")
    servo = station.joint_servo
    at.child("skills").number("max_joint_velocity", scenario.skills.max_joint_velocity,
                              minimum=0.0, maximum=servo.max_velocity, open_minimum=True,
                              why=f"{station_at.key_path}.joint_servo.max_velocity, which "
                              "the arm follows")
    at.child("skills").number("max_joint_acceleration", scenario.skills.max_joint_acceleration,
                              minimum=0.0, maximum=servo.max_acceleration, open_minimum=True,
                              why=f"{station_at.key_path}.joint_servo.max_acceleration")
    at.child("skills").number("grasp_force", scenario.skills.grasp_force, minimum=0.0,
                              maximum=max_force, open_minimum=True,
                              why=f"{station_at.key_path}.gripper_servo.max_force")
    probe = scenario.physx.stiffness
    at.child("physx").child("stiffness").number(
        "force_limit", probe.force_limit, minimum=probe.target_effort * max_force,
        maximum=max_force, why=f"from target_effort × {station_at.key_path}.gripper_servo."
        "max_force (else the target effort can never be reached) to that force")


def _check_cameras(cameras: list[CameraConfig | RealSense], at: ConfigChecker, *,
                   simulated: bool, world: bool) -> None:
    """simulated: the station is the simulated arm; world: there is a simulated world
    (the simulated arm's, or a CAN station's emulator) to render emulated cameras in."""
    names = [camera.name for camera in cameras]
    if MAIN_CAMERA not in names:
        at.fail("cameras", f"a camera named {MAIN_CAMERA!r} (the station's camera)",
                f"found the names {names}")
    for index, camera in enumerate(cameras):
        here = at.child("cameras").child(index)
        if names.count(camera.name) > 1:
            here.fail("name", "a camera name used once", f"{camera.name!r} is repeated")
        if isinstance(camera, RealSense):
            camera.check(here)
            if simulated and not camera.emulate:
                here.fail("emulate", "true on a simulated station (!SimPiper): a live or "
                          "recorded camera cannot see the simulated scene", "got false")
            if camera.emulate and not world:
                here.fail("emulate", "false on a PiperCan station without an emulator "
                          "(station.emulate: false): there is no simulated world to render",
                          "got true")
            continue
        here.number("width", camera.width, minimum=0, open_minimum=True)
        here.number("height", camera.height, minimum=0, open_minimum=True)
        here.number("fps", camera.fps, minimum=0.0, open_minimum=True)
        renderer = camera.renderer_class
        if not (isinstance(renderer, RenderEngineVtkParams | RenderEngineGlParams)
                or renderer in ("", "RenderEngineVtk", "RenderEngineGl")):
            here.fail("renderer_class", "!RenderEngineVtkParams {backend: EGL} (headless) or "
                      "!RenderEngineGlParams {}", f"got {camera.renderer_class!r}")
        if not (camera.rgb and camera.depth and camera.label):
            here.fail("rgb", "rgb, depth and label all true (the station exports all three)",
                      f"got rgb={camera.rgb}, depth={camera.depth}, label={camera.label}")
