"""Every enumerated field of the host's commands takes its documented codes (piper.md),
the largest of them included, and refuses the next one with a ValueError naming the field."""

from __future__ import annotations

import pytest

from physcap_drake.can import codec

P = codec.ParameterRequest
#: field: (encode with the field at a value, its largest documented code, the next code)
FIELDS = {
    "0x150 emergency": (lambda v: codec.encode_motion_control(v, 0, 0), 2, 3),
    "0x150 trajectory control": (lambda v: codec.encode_motion_control(0, v, 0), 8, 9),
    "0x150 drag-teach control": (lambda v: codec.encode_motion_control(0, 0, v), 7, 8),
    "0x151 control mode": (lambda v: codec.encode_mode_control(ctrl_mode=v), 7, 8),
    "0x151 move mode": (lambda v: codec.encode_mode_control(move_mode=v), 6, 7),
    "0x151 installation": (lambda v: codec.encode_mode_control(installation=v), 3, 4),
    "0x158 point": (codec.encode_move_c_point, 3, 4),
    "0x159 code": (lambda v: codec.encode_gripper_command(codec.GripperCommand(0.01, 1.0, v)),
                   3, 4),
    "0x472 motor": (codec.encode_limit_query, 7, 8),
    "0x474 motor": (lambda v: codec.encode_limit_setting(codec.LimitSetting(v)), 6, 7),
    "0x475 motor": (lambda v: codec.encode_joint_config(codec.JointConfig(v)), 7, 8),
    "0x477 query": (lambda v: codec.encode_parameter_request(P(query=v)), 4, 5),
    "0x477 reset": (lambda v: codec.encode_parameter_request(P(reset=v)), 2, 3),
    "0x477 periodic feedback": (lambda v: codec.encode_parameter_request(P(periodic=v)), 2, 3),
    "0x477 load": (lambda v: codec.encode_parameter_request(P(load=v)), 3, 4),
}


@pytest.mark.parametrize("field", FIELDS)
def test_the_largest_code_is_taken_and_the_next_refused_naming_the_field(field):
    encode, largest, beyond = FIELDS[field]
    encode(largest)
    with pytest.raises(ValueError) as error:
        encode(beyond)
    message = str(error.value)
    assert message.startswith(f"{field} must be one of ") and message.endswith(
        f"; got 0x{beyond:02X}"), message


def test_the_mode_controls_other_codes():
    assert codec.encode_mode_control(ctrl_mode=0, mit_mode=0xAD)[1][3] == 0xAD
    for mode in (2, 5, 6):  # teach, remote and linkage-teach are the arm's, not the host's
        with pytest.raises(ValueError, match="^0x151 control mode must be one of "
                                             "0x00, 0x01, 0x03, 0x04, 0x07; got"):
            codec.encode_mode_control(ctrl_mode=mode)
    with pytest.raises(ValueError, match="^0x151 mit mode must be one of 0x00, 0xAD, 0xFF; "
                                         "got 0x01$"):
        codec.encode_mode_control(mit_mode=0x01)
    with pytest.raises(ValueError, match="^0x471 motor must be one of 0x01, 0x02, 0x03, 0x04, "
                                         "0x05, 0x06, 0x07, 0xFF; got 0x08$"):
        codec.encode_motor_enable(True, 8)
