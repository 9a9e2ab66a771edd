"""AgentRecording: the agent's side of a recording, fed by the episode's hooks.

The McapRecorder in the diagram records what the station reports; this records what the agent
does, at the simulated time it happens (the sink turns it into the log time on the episode's
time base; on the simulated station time stands still while the agent thinks, so several
messages can share one log time): every transcript entry (to the Log panel, the transcript topic
and its own topic), every language-model call, each change of the agent's phase, a camera image
at every observation, the episode's particulars as metadata and, at the end, its summary.
"""

from __future__ import annotations

import dataclasses as dc
from typing import Any

from physcap_drake.agent.transcript import TranscriptEntry
from physcap_drake.recording import topics
from physcap_drake.recording.mcap_sink import McapSink


class AgentRecording:
    """Hooks for one episode. `clock()` gives the simulated time in s; `recorder` is the
    diagram's McapRecorder (for images at decisions) with its `context`; `client` is the
    language-model client whose `records` list grows with each call."""

    def __init__(self, sink: McapSink, clock, *, client=None, recorder=None, context=None):
        self._sink, self._clock = sink, clock
        self._client, self._recorder, self._context = client, recorder, context
        self._calls_written = 0

    def start(self, particulars: dict[str, Any]) -> None:
        """Writes the episode's particulars (task, agent, seed, model, commit, ...)."""
        self._sink.metadata(topics.EPISODE_METADATA, particulars)

    def on_entry(self, entry: TranscriptEntry) -> None:
        self._write_new_calls()
        self._sink.transcript_entry(self._clock(), dc.asdict(entry))

    def on_phase(self, phase: str, steps: int, oi: int) -> None:
        self._sink.json(topics.AGENT_PROGRESS, self._clock(),
                        {"phase": phase, "steps": steps, "oi": oi, "note": ""})

    def on_observe(self) -> None:
        if self._recorder is not None and self._context is not None:
            self._recorder.record_image_now(self._context)

    def finish(self, summary: dict[str, Any]) -> None:
        """Writes the remaining model calls and the summary, and flushes."""
        self._write_new_calls()
        self._sink.json(topics.EPISODE_SUMMARY, self._clock(), summary)
        self._sink.flush()

    def _write_new_calls(self) -> None:
        records = list(getattr(self._client, "records", []))
        for record in records[self._calls_written:]:
            self._sink.json(topics.LLM_CALLS, self._clock(), record.to_json())
        self._calls_written = len(records)
