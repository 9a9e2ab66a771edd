"""The topics of a recorded run and the schemas their messages follow.

Design notes: docs/design/recording.md.
"""

#: foxglove.JointStates: J1..J6 (position rad, velocity rad/s, effort N·m, measured) and the
#: gripper (position = opening in m; its effort, a fraction, is on GRIPPER_STATE).
JOINT_STATES = "/piper/joint_states"
#: physcap.GripperState (JSON): the gripper's opening (m) and measured effort as a fraction of
#: its maximum (0..1), which has no place in JointStates (whose efforts are N or N·m).
GRIPPER_STATE = "/piper/gripper"
#: physcap.ArmStatus (JSON), CAN stations only: the arm's own status as it reports it (0x2A1
#: control mode, move mode, arm status, error code, teach state; the drivers' enable and
#: status bits; the gripper's status bits).
ARM_STATUS = "/piper/arm_status"
#: physcap.LinkHealth (JSON), CAN stations only: the streaming link's watchdog (stale,
#: why, trips so far), frames lost, late and garbled, motion commands sent.
LINK = "/piper/link"
#: physcap.ArmFault (JSON): what stopped the arm (`piper.fault`), written once, at the end
#: of the step in which the station reported it.
ARM_FAULT = "/piper/fault"
#: foxglove.FrameTransforms: every body's pose in the world frame, and the fingertip frame.
TRANSFORMS = "/tf"
#: foxglove.SceneUpdate: the scene's geometry, each entity locked to its body's frame.
SCENE = "/scene"
#: foxglove.CompressedImage (JPEG): the workspace camera, at a low rate and at each decision.
CAMERA_IMAGE = "/camera/image"
#: foxglove.Log: every transcript entry as one readable line (Foxglove's Log panel).
AGENT_LOG = "/agent/log"
#: physcap.TranscriptEntry (JSON): every transcript entry, with its structured data.
AGENT_TRANSCRIPT = "/agent/transcript"
#: physcap.PlannerAnswer, physcap.PrioritizerAnswer, physcap.CodeBlock, physcap.CodeOutput,
#: physcap.AgentError, physcap.Measurement (JSON): the agent's messages by kind.
AGENT_PLANNER = "/agent/planner"
AGENT_PRIORITIZER = "/agent/prioritizer"
AGENT_CODE = "/agent/code"
AGENT_OUTPUT = "/agent/stdout"
AGENT_ERROR = "/agent/error"
AGENT_MEASUREMENT = "/agent/measurement"
#: physcap.KnowledgeEntry (JSON): each fact of the scene knowledge (a measurement, a failed
#: one, a lift's finding), once, at the end of the step in which the AgentSystem's
#: `agent.knowledge` output gained it.
AGENT_KNOWLEDGE = "/agent/knowledge"
#: physcap.LLMCall (JSON): one record per language-model call (prompt, answer, latency, tokens).
LLM_CALLS = "/agent/llm_calls"
#: physcap.AgentProgress (JSON): the AgentSystem's phase, code blocks run and OI.
AGENT_PROGRESS = "/agent/progress"
#: physcap.EpisodeSummary (JSON): written once, when the episode ends.
EPISODE_SUMMARY = "/episode/summary"

#: The fingertip frame's name in TRANSFORMS (the gripper's TCP between the finger pads).
FINGERTIP_FRAME = "fingertip"
#: The root frame every transform hangs from.
WORLD_FRAME = "world"

#: Transcript kinds that also go to their own topic.
TOPIC_OF_KIND = {
    "planner": AGENT_PLANNER,
    "prioritizer": AGENT_PRIORITIZER,
    "code": AGENT_CODE,
    "output": AGENT_OUTPUT,
    "error": AGENT_ERROR,
    "measurement": AGENT_MEASUREMENT,
}

#: MCAP metadata record holding the episode's particulars (task, agent, seed, ...).
EPISODE_METADATA = "physcap.episode"
