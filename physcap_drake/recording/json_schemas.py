"""JSON Schemas of the agent's recorded messages (the `physcap.*` schemas of `topics`).

Every agent message is a transcript entry: its kind, the code block it belongs to, the robot
time (s), a readable text and, under `data`, the structured content for that topic. Every JSON
message of a recording also carries `sim_time_s`, the simulator's time when it was written:
its log time is on the episode's time base (see `time_base`), which on the CAN station is
wall-clock time, so the simulated time would otherwise be lost.
"""

from __future__ import annotations

from typing import Any

from physcap_drake.agent.schemas import PlannerAnswer, PrioritizerRecord
from physcap_drake.recording import topics


def _entry_schema(data_schema: dict[str, Any]) -> dict[str, Any]:
    """A transcript entry whose `data` follows `data_schema`. Definitions the data schema
    refers to (pydantic's "#/$defs/...") move to the entry's root, where those references
    point once the data schema sits under `properties.data`."""
    data_schema = dict(data_schema)
    definitions = data_schema.pop("$defs", None)
    schema = {
        "$schema": JSON_SCHEMA_DIALECT,
        "type": "object",
        "properties": {
            "kind": {"type": "string"},
            "step": {"type": "integer", "description": "code block index (-1 before any)"},
            "robot_time_s": {"type": "number", "description": "robot execution time, s"},
            "text": {"type": "string"},
            "data": data_schema,
        },
        "required": ["kind", "step", "robot_time_s", "text"],
    }
    if definitions:
        schema["$defs"] = definitions
    return schema


#: The key of every JSON message's simulated time, s.
SIM_TIME_KEY = "sim_time_s"

_SIM_TIME = {"type": "number", "minimum": 0,
             "description": "the simulator's time when the message was written, s (the log "
                            "time is on the episode's time base: see the physcap.time "
                            "metadata)"}


def _with_sim_time(schema: dict[str, Any]) -> dict[str, Any]:
    """`schema` (an object's) with the required `sim_time_s` property every recorded JSON
    message has."""
    return {**schema, "properties": {**schema["properties"], SIM_TIME_KEY: _SIM_TIME},
            "required": [*schema.get("required", []), SIM_TIME_KEY]}


#: The JSON Schema version of every schema here (pydantic writes 2020-12 schemas).
JSON_SCHEMA_DIALECT = "https://json-schema.org/draft/2020-12/schema"

_ANY_OBJECT = {"type": "object"}
_STRING = {"type": "string"}

_CODE_BLOCK = {"type": "object", "properties": {
    "thought": _STRING, "code": _STRING, "decision": _STRING, "target": _STRING}}
_CODE_OUTPUT = {"type": "object", "properties": {"stdout": _STRING}}
_AGENT_ERROR = {"type": "object", "properties": {"kind": _STRING, "error": _STRING}}
_MEASUREMENT = {"type": "object", "properties": {
    "subject": _STRING, "prop": _STRING, "value": {"type": "number"}, "unit": _STRING,
    "ok": {"type": "boolean"}, "note": _STRING, "robot_time_s": {"type": "number"}}}
_KNOWLEDGE = {"type": "object", "properties": {
    **_MEASUREMENT["properties"], "sentence": _STRING, "detail": _STRING},
    "required": ["subject", "prop", "unit", "ok"]}

_LLM_CALL = {"type": "object", "properties": {
    "role": _STRING, "model": _STRING, "system": _STRING, "prompt": _STRING,
    "response": _STRING, "latency_s": {"type": "number", "description": "wall clock, s"},
    "input_tokens": {"type": "integer"}, "output_tokens": {"type": "integer"},
    "images": {"type": "integer"}, "key": _STRING, "attempts": {"type": "integer"}}}
_PROGRESS = {"type": "object", "properties": {
    "phase": _STRING, "steps": {"type": "integer"}, "oi": {"type": "integer"},
    "note": _STRING}}
_GRIPPER = {"type": "object", "properties": {
    "opening_m": {"type": "number", "description": "gap between the fingers, m"},
    "effort": {"type": "number", "description": "measured effort as a fraction of the "
                                                "gripper's maximum, 0..1 (no unit; the "
                                                "paper's f-hat)"}},
    "required": ["opening_m", "effort"]}
_INTEGER, _BOOLEAN = {"type": "integer"}, {"type": "boolean"}
_SIX_BOOLEANS = {"type": "array", "items": _BOOLEAN, "minItems": 6, "maxItems": 6}
_ARM_STATUS = {"type": "object", "properties": {
    "ctrl_mode": _STRING, "move_mode": _STRING, "arm_status": _STRING,
    "error_code": {"type": "integer", "description": "0x2A1 err_code: bits 0-5 "
                   "communication error of J1-J6, bits 8-13 J1-J6 at an angle limit"},
    "errors": _STRING, "teach_status": _INTEGER, "motion_status": _INTEGER,
    "enabled": _SIX_BOOLEANS,
    "driver_status": {"type": "array", "items": _INTEGER, "description": "0x261-0x266 "
                      "byte 5 of J1-J6 (bit 6 enabled, 4 collision, 7 stall)"},
    "gripper_status": {"type": "integer", "description": "0x2A8 byte 6 (bit 6 enabled, "
                       "7 zeroed, 0-5 faults)"},
    "gripper_errors": {"type": "array", "items": _STRING}},
    "required": ["ctrl_mode", "move_mode", "arm_status", "error_code", "enabled"]}
_LINK = {"type": "object", "properties": {
    "stale": {"type": "boolean", "description": "the watchdog holds the arm"},
    "reason": _STRING, "fault": _STRING,
    "watchdog_trips": {"type": "integer", "description": "stale spells so far"},
    "commands_sent": _INTEGER,
    "lost_fraction": {"type": "number", "description": "feedback frames lost over the "
                      "last 16 cycles, 0..1"},
    "late_s": {"type": "number", "description": "how late the newest feedback frame "
               "arrived, s"},
    "garbled_frames": {"type": "integer", "description": "rejected so far"}},
    "required": ["stale", "watchdog_trips", "commands_sent"]}
_ARM_FAULT = {"type": "object", "properties": {
    "fault": {"type": "string", "minLength": 1, "description": "what stopped the arm: an "
              "error state it reported, its feedback stale too long, or the streaming "
              "process silent (the station's piper.fault)"}},
    "required": ["fault"]}
_SUMMARY = {"type": "object", "properties": {
    "task": _STRING, "agent": _STRING, "seed": {"type": "integer"},
    "success": {"type": ["boolean", "null"]}, "oi": {"type": "integer"},
    "robot_time_s": {"type": "number"}}}


def agent_schemas() -> dict[str, tuple[str, dict[str, Any]]]:
    """topic -> (schema name, JSON Schema) for every JSON topic of a recording."""
    schemas = {
        topics.AGENT_TRANSCRIPT: ("physcap.TranscriptEntry", _entry_schema(_ANY_OBJECT)),
        topics.AGENT_PLANNER: ("physcap.PlannerAnswer",
                               _entry_schema(PlannerAnswer.model_json_schema())),
        topics.AGENT_PRIORITIZER: ("physcap.PrioritizerAnswer",
                                   _entry_schema(PrioritizerRecord.model_json_schema())),
        topics.AGENT_CODE: ("physcap.CodeBlock", _entry_schema(_CODE_BLOCK)),
        topics.AGENT_OUTPUT: ("physcap.CodeOutput", _entry_schema(_CODE_OUTPUT)),
        topics.AGENT_ERROR: ("physcap.AgentError", _entry_schema(_AGENT_ERROR)),
        topics.AGENT_MEASUREMENT: ("physcap.Measurement", _entry_schema(_MEASUREMENT)),
        topics.AGENT_KNOWLEDGE: ("physcap.KnowledgeEntry", _KNOWLEDGE),
        topics.GRIPPER_STATE: ("physcap.GripperState", _GRIPPER),
        topics.ARM_STATUS: ("physcap.ArmStatus", _ARM_STATUS),
        topics.LINK: ("physcap.LinkHealth", _LINK),
        topics.ARM_FAULT: ("physcap.ArmFault", _ARM_FAULT),
        topics.LLM_CALLS: ("physcap.LLMCall", _LLM_CALL),
        topics.AGENT_PROGRESS: ("physcap.AgentProgress", _PROGRESS),
        topics.EPISODE_SUMMARY: ("physcap.EpisodeSummary", _SUMMARY),
    }
    return {topic: (name, _with_sim_time(schema)) for topic, (name, schema) in schemas.items()}
