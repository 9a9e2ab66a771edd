"""The gripper command selector through its ports: who commands the gripper, and that the
station's every plant step does not re-run its Python (only a change of `probe.active`)."""

from __future__ import annotations

from physcap_drake.physx.gripper_command_selector import make_gripper_command_selector
from physcap_drake.station import ports


def _fixed(active: float):
    selector = make_gripper_command_selector()
    context = selector.CreateDefaultContext()
    for source, opening, force in (("executor", 0.04, 10.0), ("probe", 0.01, 3.0)):
        selector.GetInputPort(f"{source}.{ports.GRIPPER_POSITION}").FixValue(context, [opening])
        selector.GetInputPort(f"{source}.{ports.GRIPPER_FORCE_LIMIT}").FixValue(context, [force])
    active_port = selector.GetInputPort("probe.active").FixValue(context, [active])
    return selector, context, active_port


def _commands(selector, context) -> tuple[float, float]:
    return (selector.GetOutputPort(ports.GRIPPER_POSITION).Eval(context)[0],
            selector.GetOutputPort(ports.GRIPPER_FORCE_LIMIT).Eval(context)[0])


def test_the_executor_commands_unless_the_probe_is_active():
    selector, context, active = _fixed(0.0)
    assert _commands(selector, context) == (0.04, 10.0)
    active.GetMutableData().set_value([1.0])
    assert _commands(selector, context) == (0.01, 3.0)


def test_the_source_is_not_recomputed_when_only_time_or_commands_change():
    selector, context, active = _fixed(0.0)
    source = selector.GetSubsystemByName("active_source")
    source_context = source.GetMyContextFromRoot(context)
    entry = source.GetOutputPort("source").cache_entry()
    _commands(selector, context)
    context.SetTime(0.004)
    selector.GetInputPort(f"executor.{ports.GRIPPER_POSITION}").FixValue(context, [0.03])
    assert not entry.is_out_of_date(source_context)
    assert _commands(selector, context) == (0.03, 10.0)
    active.GetMutableData().set_value([1.0])
    assert entry.is_out_of_date(source_context)
