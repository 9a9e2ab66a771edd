"""Thought: the policy's decision computing on a worker thread while the diagram runs on.

Design notes: docs/design/agent.md.
"""

from __future__ import annotations

import threading
from concurrent.futures import Future

from physcap_drake.agent.loop import AgentPolicy


class Thought:
    """`policy.decide(...)` on a daemon worker thread (a resource handle: the thread is never
    joined, so a fault never waits for a model)."""

    def __init__(self, policy: AgentPolicy, *args):
        self._policy = policy
        self.future: Future = Future()
        self.thread = threading.Thread(target=self._run, args=args, name="agent-thought",
                                       daemon=True)
        self.thread.start()

    def _run(self, *args) -> None:
        try:
            self.future.set_result(self._policy.decide(*args))
        except BaseException as error:  # noqa: BLE001 - handed to the event that collects it
            self.future.set_exception(error)

    def give_up(self) -> None:
        """The episode ended while the thought ran: it writes nothing more."""
        self._policy.notes.silence(self.thread)
