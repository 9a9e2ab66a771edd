"""Model calls of a Ray episode task, made by a zero-CPU actor so the task's CPU is free
while a model thinks.

Design notes: docs/design/eval.md.
"""

from __future__ import annotations

import ray

from physcap_drake.agent.llm import make_llm
from physcap_drake.agent.llm.base import LLMClient, LLMRequest, LLMResponse
from physcap_drake.agent.llm.factory import ModelSettings
from physcap_drake.agent.llm.recording import RecordingClient

#: Backends that answer in the task's own process (no network wait to overlap).
OFFLINE_BACKENDS = ("reference", "replay")


def is_offline(llm: str | ModelSettings) -> bool:
    """Whether the backend (a spec, or the settings of `physcap eval`'s model flags) answers
    in the task's own process."""
    spec = llm.llm if isinstance(llm, ModelSettings) else llm
    return spec.strip().partition(":")[0] in OFFLINE_BACKENDS


@ray.remote(num_cpus=0)
class ModelCaller:
    """Holds one episode's backend client and answers its requests (reserves no CPU)."""

    def __init__(self, llm: str | ModelSettings, model: str | None, seed: int):
        self._client = make_llm(llm, model, seed=seed).inner

    def identity(self) -> tuple[str, str]:
        return self._client.name, self._client.model

    def complete(self, request: LLMRequest) -> tuple[LLMResponse, int]:
        response = self._client.complete(request)
        return response, int(getattr(self._client, "last_attempts", 1) or 1)


class RayModelClient:
    """An LLMClient whose calls go to a `ModelCaller` actor; `last_attempts` is the attempts
    the actor's backend made on the latest call."""

    def __init__(self, caller):
        self._caller = caller
        self.name, self.model = ray.get(caller.identity.remote())
        self.last_attempts = 1

    def complete(self, request: LLMRequest) -> LLMResponse:
        try:
            response, self.last_attempts = ray.get(self._caller.complete.remote(request))
        except ray.exceptions.RayTaskError as error:  # the backend's own exception
            cause = error.cause
            raise (cause if isinstance(cause, Exception) else error) from None
        return response


def episode_client(llm: str | ModelSettings, model: str | None, seed: int
                   ) -> LLMClient | None:
    """The client an episode task uses: a recorded remote client for a networked backend,
    None for an offline one (the episode then builds its own in-process)."""
    if is_offline(llm):
        return None
    return RecordingClient(RayModelClient(ModelCaller.remote(llm, model, seed)))
