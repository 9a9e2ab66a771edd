"""FaultSource: a synthetic station fault, for the systems that read `piper.fault`."""

from __future__ import annotations

from pydrake.common.value import AbstractValue, Value
from pydrake.systems.framework import Context, LeafSystem, State

from physcap_drake.station import ports


class FaultSource(LeafSystem):
    """Latches `text` in its own periodic event (every `period` s) once the time is
    `at` s or later, as a station's interface does; never, with `at` None.

    Output ports: piper.fault (str, "" until then).
    State: the fault (str).
    """

    def __init__(self, text: str, at: float | None, period: float = 0.005):
        super().__init__()
        self._text, self._at = text, at
        self._fault = self.DeclareAbstractState(Value(""))
        self.DeclarePeriodicUnrestrictedUpdateEvent(period, 0.0, self._latch)
        self.DeclareAbstractOutputPort(
            ports.ARM_FAULT, lambda: AbstractValue.Make(""),
            lambda context, output: output.set_value(self.fault(context)),
            {self.abstract_state_ticket(self._fault)})

    def fault(self, context: Context) -> str:
        return context.get_abstract_state(self._fault).get_value()

    def _latch(self, context: Context, state: State) -> None:
        if self._at is not None and context.get_time() >= self._at - 1e-12:
            state.get_mutable_abstract_state(self._fault).set_value(self._text)
