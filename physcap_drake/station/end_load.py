"""EndLoadWeight: the emulated firmware's end-load compensation as a force on the plant.

Design notes: docs/design/station.md.
"""

from __future__ import annotations

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.multibody.math import SpatialForce
from pydrake.multibody.plant import ExternallyAppliedSpatialForce_, MultibodyPlant
from pydrake.multibody.tree import Frame
from pydrake.systems.framework import Context, LeafSystem

from physcap_drake.weak_method import weak_method

GRAVITY = 9.81  # m/s²

_Force = ExternallyAppliedSpatialForce_[float]


class EndLoadWeight(LeafSystem):
    """The upward force that carries an end load's weight at `tcp` (see the design notes).

    Input port: mass (1, kg), the end load the firmware compensates (0: none).
    Output port: spatial_forces (a list of ExternallyAppliedSpatialForce, for the plant's
        applied spatial force input): one force of mass · g upward (world +z, N) at the
        tcp's origin on its body; none when the mass is 0.
    No state.
    """

    def __init__(self, plant: MultibodyPlant, tcp: Frame):
        super().__init__()
        self._body = tcp.body().index()
        # Where the tcp sits on its body, in the body's frame, m.
        self._p_BoTcp_B = tcp.GetFixedPoseInBodyFrame().translation().copy()
        self._mass = self.DeclareVectorInputPort("mass", 1)
        self.DeclareAbstractOutputPort("spatial_forces", lambda: AbstractValue.Make([_Force()]),
                                       weak_method(self._output), {self._mass.ticket()})

    def _output(self, context: Context, output: AbstractValue) -> None:
        mass = float(self._mass.Eval(context)[0])
        if mass == 0.0:
            output.set_value([])
            return
        force = _Force()
        force.body_index = self._body
        force.p_BoBq_B = self._p_BoTcp_B
        force.F_Bq_W = SpatialForce(tau=np.zeros(3), f=np.array([0.0, 0.0, mass * GRAVITY]))
        output.set_value([force])
