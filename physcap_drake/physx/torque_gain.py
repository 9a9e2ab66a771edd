"""Fitting the arm's torque sensor gains with a weight of known mass.

Design notes: docs/design/physx.md; why the weight is taken as centred on the grasp point:
docs/rig_calibration.md ("Gain fit on the emulated twin").
"""

from __future__ import annotations

import numpy as np

from physcap_drake.physx.mass_estimator import GRAVITY, MassEstimator, TorqueWindow, as_gain

#: A joint whose expected load torque is below this share of the largest keeps gain 1.
MIN_SHARE = 0.15


def fit_torque_gain(estimator: MassEstimator, empty: TorqueWindow, loaded: TorqueWindow,
                    mass_kg: float, *, min_share: float = MIN_SHARE) -> np.ndarray:
    """Each arm joint's torque sensor gain (6,), from one get_mass measurement (its `empty`
    and `loaded` windows) of a weight of known `mass_kg` held with its centre of mass at the
    fingertip point, with the estimator's model of the arm. The estimator's own gains are
    not used: the reported change is taken as it is.

    The weight's offset from the fingertip point is not fitted: at one pose it moves the
    load torque of every pitch joint alike, as their gains do. A weight d (m) off the grasp
    point horizontally shifts a joint's fitted gain by about d over its lever.

    Raises ValueError if the mass is not positive or the fitted gains leave [0.5, 2] (the
    weight was not held, or the mass given is not the weight's).
    """
    if not mass_kg > 0.0:
        raise ValueError(f"the calibration weight's mass must be positive, got {mass_kg} kg")
    reported = np.asarray(loaded.torque - empty.torque, dtype=float)
    own = estimator.own_torque_change(empty, loaded)
    expected_load = mass_kg * GRAVITY * estimator.vertical_jacobian(loaded.position)
    loaded_joints = np.abs(expected_load) >= min_share * np.abs(expected_load).max()
    gain = np.where(loaded_joints,
                    reported / np.where(loaded_joints, expected_load + own, 1.0), 1.0)
    try:
        return as_gain(gain)
    except ValueError as error:
        raise ValueError(f"the fitted gains do not look like a sensor's ({error}): was the "
                         f"{1000 * mass_kg:.0f} g weight held during the loaded window?"
                         ) from None
