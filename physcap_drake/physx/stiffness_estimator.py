"""StiffnessEstimator: squeezes an object in small steps and measures how far the fingers
travel between first contact and a fixed normalized effort."""

from __future__ import annotations

import dataclasses as dc
import enum
import math

from pydrake.common.value import AbstractValue
from pydrake.systems.framework import BasicVector, Context, EventStatus, LeafSystem, State

from physcap_drake.immutable_state import Immutable
from physcap_drake.physx.physx_config import StiffnessProbeConfig
from physcap_drake.physx.stiffness_levels import (
    StiffnessThresholds,
    deformation_at_effort,
    level_from_deformation,
    majority_level,
)
from physcap_drake.station import ports
from physcap_drake.weak_method import weak_method

#: A release is complete when the fingers are this close to the release opening, m, and no
#: effort is left; the next squeeze starts after at most MAX_RELEASE_TICKS dwells anyway.
RELEASED_TOLERANCE = 0.0005
MAX_RELEASE_TICKS = 20
#: Notes kept of rejected contacts (friction, passing spikes); more are only counted, so the
#: result stays short whatever the drive does.
MAX_REJECTION_NOTES = 3
#: A squeeze that closed fully with its effort back below `contact_effort` after it had
#: risen to this many times that lost the object (it slipped or tipped out of the fingers).
SLIP_FACTOR = 3.0
#: Slack when comparing event times, s.
TIME_EPSILON = 1e-6
#: The estimator's ports besides the gripper's signals.
SQUEEZE_PORT = "squeeze"
RESULT_PORT = "result"
ACTIVE_PORT = "active"


class Phase(enum.Enum):
    IDLE = "idle"
    SEEK_CONTACT = "seek contact"  # closing in contact steps until the effort rises
    BACK_OFF = "back off"  # reopened slightly: does the effort drop (real contact)?
    SQUEEZE = "squeeze"  # closing in squeeze steps, recording (opening, effort)
    RELEASE = "release"  # reopened past the contact before the next squeeze
    DONE = "done"


@dc.dataclass(frozen=True)
class SqueezeRequest(Immutable):
    """A request on the StiffnessEstimator's `squeeze` port: a new `sequence` number (1, 2,
    ...) starts probing the object between the open fingers, or with `stop` ends the running
    probe (the gripper goes back to the skill executor)."""

    sequence: int = 0
    stop: bool = False


@dc.dataclass(frozen=True)
class ProbeState(Immutable):
    """Everything the probe remembers (kept in the Context as one abstract state).

    sequence: the squeeze request served. command: the commanded opening, m. free_effort:
    the effort read before the last rise.
    contact: (opening m, effort) where the effort rose, and contact_command the command (m)
    that reading showed. d0: the accepted contact opening, m.
    samples: (opening m, effort) pairs of the running squeeze. deformations_mm: one per
    finished squeeze (NaN for a failed one). failures: why each failed squeeze failed.
    notes: those reasons and the contacts rejected (at most MAX_REJECTION_NOTES of the
    latter; `rejections` counts them all, `squeeze_rejections` those of the running squeeze).
    issued: the latest commands as (time s, opening m), to tell which one a reading shows.
    read_after: the feedback is not read before this time (s): a step the next decision
    depends on is held until it shows.
    """

    phase: Phase = Phase.IDLE
    sequence: int = 0
    command: float = 0.0
    free_effort: float = 0.0
    contact: tuple[float, float] | None = None
    d0: float = math.nan
    samples: tuple[tuple[float, float], ...] = ()
    deformations_mm: tuple[float, ...] = ()
    notes: tuple[str, ...] = ()
    release_ticks: int = 0
    start_opening: float = math.inf
    contact_command: float = math.nan
    rejections: int = 0
    squeeze_rejections: int = 0
    failures: tuple[str, ...] = ()
    issued: tuple[tuple[float, float], ...] = ()
    read_after: float = -math.inf


@dc.dataclass(frozen=True)
class StiffnessResult(Immutable):
    """The outcome of a probe: one deformation (mm) and level per squeeze, the vote (`level`,
    0 if most squeezes failed), `failures` the reason of each failed squeeze (or of a probe
    stopped early), `notes` those and the contacts rejected."""

    level: int
    deformations_mm: tuple[float, ...]
    levels: tuple[int, ...]
    notes: tuple[str, ...]
    failures: tuple[str, ...] = ()


@dc.dataclass(frozen=True)
class StiffnessReport(Immutable):
    """The StiffnessEstimator's `result` output: about squeeze request `sequence` (0: none
    yet), whether its squeezes are `finished`, and the `result` of those done so far."""

    sequence: int = 0
    finished: bool = False
    result: StiffnessResult = StiffnessResult(0, (), (), ())


class StiffnessEstimator(LeafSystem):
    """Drives the gripper through `squeezes` squeezes of an object between the fingers and
    classifies its stiffness.

    Each squeeze: (1) close in `contact_step` steps until the normalized effort reaches
    `contact_effort`; (2) undo that step and reopen to `backoff` past the measured fingers
    (the command may lie well inside a rigid object): a real contact loses at least
    `backoff_drop` of its effort rise, friction in the drive does not (then closing
    resumes); the opening where the effort rose is d0; (3) close in `squeeze_step` steps
    recording (d_i, f̂_i) until f̂ reaches `target_effort`, and take Δd = |d0 − d(f̂*)|
    (mm, interpolated) less the gripper's own `gripper_offset_mm` (at least 0); if the
    first reading back at the contact command shows no effort, the rise was a passing
    spike and the search goes on;
    (4) reopen to d0 + `release` (at most to the opening it started from). A squeeze fails,
    its reason in `failures`, when the fingers close fully (no contact found, none passed
    the back-off test, the effort never reached the target, or it fell back: the object
    slipped). Every step is held `dwell` s before the gripper is read.

    `command_latency` (s) is the station's: a command shows in the feedback that much later
    (about 0.1 s over CAN, none on the simulated station). Closing steps go on every `dwell`
    meanwhile (each reading pairs an opening with the effort of the same moment, whichever
    step it shows), but a reading is taken for the command it shows: the contact is where
    the command `command_latency` earlier put the fingers, and the steps a decision rests on
    (the back-off, the return to the contact) are held `command_latency` + `dwell` before
    they are read. Closing fully fails only once the last closing step had time to show.

    A probe starts at the first step (every `dwell` s) after a new request arrives on the
    `squeeze` port, closing from the opening measured then (the object between the open
    fingers); a `stop` request ends it. The squeezes' deformations, levels and vote are
    published on `result` as they come, `finished` once all `squeezes` are done.

    It reads only gripper.position_measured and gripper.effort_measured, and while probing
    commands the gripper through its own outputs (see GripperCommandSelector).

    Input ports: gripper.position_measured (1, m), gripper.effort_measured (1, 0..1),
        squeeze (SqueezeRequest).
    Output ports: gripper.position (1, m), gripper.force_limit (1, N), active (1: 1 while
        probing, else 0), result (StiffnessReport).
    State (abstract): ProbeState, the squeeze request served, the gripper command, the
        contact found, the readings and the report so far.
    """

    def __init__(self, config: StiffnessProbeConfig, thresholds: StiffnessThresholds, *,
                 command_latency: float):
        super().__init__()
        if not command_latency >= 0.0:
            raise ValueError(f"command_latency must be >= 0 s, got {command_latency}")
        self._config = config
        self._thresholds = thresholds
        self._latency = float(command_latency)
        # Commands remembered: enough to reach back over the latency, and the one before.
        self._kept_commands = math.ceil(self._latency / config.dwell - TIME_EPSILON) + 2
        self._opening = self.DeclareVectorInputPort(ports.GRIPPER_POSITION_MEASURED, 1)
        self._effort = self.DeclareVectorInputPort(ports.GRIPPER_EFFORT_MEASURED, 1)
        self._request = self.DeclareAbstractInputPort(SQUEEZE_PORT,
                                                      AbstractValue.Make(SqueezeRequest()))
        self._state = self.DeclareAbstractState(AbstractValue.Make(ProbeState()))
        self.DeclarePeriodicUnrestrictedUpdateEvent(config.dwell, 0.0, self._step)
        ticket = {self.abstract_state_ticket(self._state)}
        self.DeclareVectorOutputPort(ports.GRIPPER_POSITION, 1, self._output_command, ticket)
        self.DeclareVectorOutputPort(ports.GRIPPER_FORCE_LIMIT, 1, self._output_force, ticket)
        self.DeclareVectorOutputPort(ACTIVE_PORT, 1, self._output_active, ticket)
        self.DeclareAbstractOutputPort(RESULT_PORT, lambda: AbstractValue.Make(StiffnessReport()),
                                       weak_method(self._output_result), ticket)

    @property
    def thresholds(self) -> StiffnessThresholds:
        return self._thresholds

    def _get(self, context: Context) -> ProbeState:
        return context.get_abstract_state(self._state).get_value()

    def _result(self, state: ProbeState) -> StiffnessResult:
        levels = tuple(level_from_deformation(d, self._thresholds) for d in state.deformations_mm)
        left_out = state.rejections - MAX_REJECTION_NOTES
        notes = state.notes + ((f"{left_out} more contacts rejected",) if left_out > 0 else ())
        return StiffnessResult(majority_level(list(levels)), state.deformations_mm, levels,
                               notes, state.failures)

    # The probe's steps ------------------------------------------------------------------------

    def _step(self, context: Context, state: State) -> EventStatus | None:
        now = context.get_time()
        current = self._get(context)
        request = self._request.Eval(context)
        started = request.sequence != current.sequence
        if started:
            if request.stop:
                current = dc.replace(current, phase=Phase.IDLE, sequence=request.sequence)
            else:  # start closing from where the fingers are, with this dwell's step
                opening = float(self._opening.Eval(context)[0])
                current = ProbeState(Phase.SEEK_CONTACT, request.sequence, command=opening,
                                     start_opening=opening, issued=((now, opening),))
            state.get_mutable_abstract_state(self._state).set_value(current)
        # Idle, done, or the step a decision rests on does not show in the feedback yet.
        if (current.phase in (Phase.IDLE, Phase.DONE)
                or now < current.read_after - TIME_EPSILON):
            return None if started else EventStatus.DidNothing()
        d = float(self._opening.Eval(context)[0])
        f = float(self._effort.Eval(context)[0])
        handler = {
            Phase.SEEK_CONTACT: self._seek_contact,
            Phase.BACK_OFF: self._back_off,
            Phase.SQUEEZE: self._squeeze,
            Phase.RELEASE: self._release,
        }[current.phase]
        updated = handler(current, d, f, now)
        if updated.command != current.command:
            issued = current.issued + ((now, updated.command),)
            updated = dc.replace(updated, issued=issued[-self._kept_commands:])
        state.get_mutable_abstract_state(self._state).set_value(updated)
        return None

    def _shown_command(self, s: ProbeState, now: float) -> float:
        """The command (m) the feedback read at `now` shows: the latest issued at least the
        command latency earlier (the oldest remembered if none is that old)."""
        shown = s.issued[0][1] if s.issued else s.command
        for issued_at, command in s.issued:
            if issued_at <= now - self._latency + TIME_EPSILON:
                shown = command
        return shown

    def _hold(self, s: ProbeState, now: float, **changes) -> ProbeState:
        """`s` with `changes`, its command read only once it shows and was held `dwell`."""
        return dc.replace(s, read_after=now + self._latency + self._config.dwell, **changes)

    def _reject(self, s: ProbeState, note: str, **changes) -> ProbeState:
        notes = s.notes + ((note,) if s.rejections < MAX_REJECTION_NOTES else ())
        return dc.replace(s, notes=notes, rejections=s.rejections + 1,
                          squeeze_rejections=s.squeeze_rejections + 1, **changes)

    def _close_by(self, s: ProbeState, step: float, now: float, **changes) -> ProbeState:
        command = s.command - step
        if command < 0.0:
            if s.issued and now - s.issued[-1][0] < self._latency - TIME_EPSILON:
                return dc.replace(s, **changes)  # the last step does not show yet
            return self._finish_squeeze(s, math.nan, self._why_closed(s))
        return dc.replace(s, command=command, **changes)

    def _why_closed(self, s: ProbeState) -> str:
        """Why a squeeze whose fingers closed fully failed."""
        c = self._config
        if s.phase is Phase.SQUEEZE:
            top, last = max(f for _, f in s.samples), s.samples[-1][1]
            if last < c.contact_effort <= top / SLIP_FACTOR:
                return (f"the object slipped: the effort fell from {top:.2f} to {last:.2f} "
                        f"after contact at {1000 * s.d0:.1f} mm, and the fingers closed fully")
            return (f"effort never reached {c.target_effort:.2f}: at most {top:.2f} after "
                    f"contact at {1000 * s.d0:.1f} mm, and the fingers closed fully")
        if s.squeeze_rejections:
            return (f"no contact passed the back-off test ({s.squeeze_rejections} rejected, "
                    "see the notes) before the fingers closed fully")
        return (f"no contact found: the effort stayed below {c.contact_effort:.2f} until "
                "the fingers closed fully")

    def _seek_contact(self, s: ProbeState, d: float, f: float, now: float) -> ProbeState:
        c = self._config
        if f >= c.contact_effort:
            # Undo the step shown and open `backoff` past the fingers: a soft servo leaves
            # the command well inside a rigid object, and reopening from the command alone
            # would never free the contact.
            shown = self._shown_command(s, now)
            return self._hold(s, now, phase=Phase.BACK_OFF, contact=(d, f),
                              contact_command=shown,
                              command=max(shown + c.contact_step, d) + c.backoff)
        return self._close_by(s, c.contact_step, now, free_effort=f)

    def _back_off(self, s: ProbeState, d: float, f: float, now: float) -> ProbeState:
        c = self._config
        assert s.contact is not None  # set on entering BACK_OFF
        d_contact, f_contact = s.contact
        if f_contact - f >= c.backoff_drop * (f_contact - s.free_effort):
            return self._hold(s, now, phase=Phase.SQUEEZE, d0=d_contact,
                              command=s.contact_command, samples=((d_contact, f_contact),))
        note = f"effort {f_contact:.2f} at {1000 * d_contact:.1f} mm did not drop on back-off"
        return self._close_by(self._reject(s, f"rejected as friction: {note}",
                                           phase=Phase.SEEK_CONTACT, command=s.contact_command),
                              c.contact_step, now)

    def _squeeze(self, s: ProbeState, d: float, f: float, now: float) -> ProbeState:
        c = self._config
        if len(s.samples) == 1 and f < c.contact_effort:
            # Back at the contact command the effort is gone: it was a passing spike (drive
            # friction), not the object. Keep looking for the real contact.
            note = f"rejected as a passing spike: effort {s.samples[0][1]:.2f} at " \
                   f"{1000 * s.samples[0][0]:.1f} mm did not return"
            return self._close_by(self._reject(s, note, phase=Phase.SEEK_CONTACT, contact=None,
                                               d0=math.nan, samples=()),
                                  c.contact_step, now)
        samples = s.samples + ((d, f),)
        if f >= c.target_effort:
            deformation = deformation_at_effort(s.d0, list(samples), c.target_effort)
            return self._finish_squeeze(s, max(deformation - c.gripper_offset_mm, 0.0))
        return self._close_by(dc.replace(s, samples=samples), c.squeeze_step, now)

    def _finish_squeeze(self, s: ProbeState, deformation_mm: float, note: str = "") -> ProbeState:
        reopen = min((s.d0 if math.isfinite(s.d0) else s.command) + self._config.release,
                     s.start_opening)
        failure = (f"squeeze {len(s.deformations_mm) + 1}: {note}",) if note else ()
        return dc.replace(s, phase=Phase.RELEASE, command=reopen, samples=(),
                          deformations_mm=s.deformations_mm + (deformation_mm,),
                          notes=s.notes + failure, failures=s.failures + failure)

    def _release(self, s: ProbeState, d: float, f: float, now: float) -> ProbeState:
        still_opening = abs(d - s.command) > RELEASED_TOLERANCE or f >= self._config.contact_effort
        if still_opening and s.release_ticks < MAX_RELEASE_TICKS:
            return dc.replace(s, release_ticks=s.release_ticks + 1)
        if len(s.deformations_mm) >= self._config.squeezes:
            return dc.replace(s, phase=Phase.DONE)
        return dc.replace(s, phase=Phase.SEEK_CONTACT, contact=None, d0=math.nan,
                          release_ticks=0, squeeze_rejections=0)

    # Outputs ------------------------------------------------------------------------------------

    def _output_command(self, context: Context, output: BasicVector) -> None:
        output.SetAtIndex(0, max(self._get(context).command, 0.0))

    def _output_force(self, context: Context, output: BasicVector) -> None:
        output.SetAtIndex(0, self._config.force_limit)

    def _output_result(self, context: Context, output: AbstractValue) -> None:
        state = self._get(context)
        output.set_value(StiffnessReport(state.sequence, state.phase is Phase.DONE,
                                         self._result(state)))

    def _output_active(self, context: Context, output: BasicVector) -> None:
        active = self._get(context).phase not in (Phase.IDLE, Phase.DONE)
        output.SetAtIndex(0, 1.0 if active else 0.0)
