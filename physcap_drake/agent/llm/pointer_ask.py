"""Lets the VLM pointer (perception.vlm_pointer) use any backend that takes images."""

from __future__ import annotations

from collections.abc import Callable

from physcap_drake.agent.llm.base import LLMClient, LLMRequest

POINTER_SYSTEM = ("You locate objects in photographs of a tabletop for a robot arm. Answer "
                  "exactly in the format the question asks for.")


def pointer_ask(client: LLMClient) -> Callable[[bytes, str], str]:
    """An `ask(jpeg, prompt) -> answer text` for VlmPointer that sends the image and the
    question to `client` as a "pointer" request (recorded like every other call)."""

    def ask(jpeg: bytes, prompt: str) -> str:
        request = LLMRequest(role="pointer", system=POINTER_SYSTEM, prompt=prompt,
                             images=(jpeg,))
        return client.complete(request).text

    return ask
