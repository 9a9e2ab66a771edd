"""The language-model options of the commands that run the agent, in one place.

`ModelChoice` gathers them (backend spec, model name, Gemini on Vertex AI, and how calls are
made: deadline, retries, schema mode, images, sampling, the key's variable) and builds the
client; its checks speak in the command line's own words (flags and environment variables,
not the Python API's parameter names). Add an option here: an Annotated alias for the
command's signature, a field, and its use in `settings`.
"""

from __future__ import annotations

import dataclasses as dc
import os
from typing import Annotated, Any

import typer

from physcap_drake.agent.llm import LLMClient, LLMError, ModelSettings, check_client
from physcap_drake.agent.llm.chat_format import SCHEMA_MODES
from physcap_drake.agent.llm.factory import DEFAULT_RETRIES, DEFAULT_TIMEOUT_S, VALID_SPECS
from physcap_drake.agent.llm.gemini import API_KEY_VARIABLES
from physcap_drake.commands.common import MODEL_FAILURE, describe_error, fail

PANEL = "Language model"

Llm = Annotated[str, typer.Option(
    "--llm", metavar="SPEC", rich_help_panel=PANEL,
    help="The language model: " + ", ".join(VALID_SPECS) + ".")]
Model = Annotated[str | None, typer.Option(
    "--model", metavar="NAME", rich_help_panel=PANEL,
    help="Model name for the backend (default: the backend's own).")]
VertexProject = Annotated[str | None, typer.Option(
    "--vertex-project", metavar="PROJECT", rich_help_panel=PANEL,
    help="With --llm gemini: use Gemini on Vertex AI in this Google Cloud project "
         "(credentials from Application Default Credentials; needs --vertex-location).")]
VertexLocation = Annotated[str | None, typer.Option(
    "--vertex-location", metavar="REGION", rich_help_panel=PANEL,
    help="With --llm gemini and --vertex-project: the Vertex AI region, e.g. us-central1.")]
Timeout = Annotated[float | None, typer.Option(
    "--timeout", metavar="S", min=0.1, rich_help_panel=PANEL,
    help=f"Deadline of one model call, s: the whole answer, however slowly it comes "
         f"(default {DEFAULT_TIMEOUT_S:g}).")]
Retries = Annotated[int | None, typer.Option(
    "--retries", metavar="N", min=0, max=20, rich_help_panel=PANEL,
    help=f"Further attempts after a transient failure: 429, 5xx, a broken or late answer "
         f"(default {DEFAULT_RETRIES}).")]
SchemaMode = Annotated[str | None, typer.Option(
    "--schema-mode", metavar="MODE", rich_help_panel=PANEL,
    help="With --llm openai or openai-compatible: how the server is told the answer's JSON "
         "Schema: json_schema (default), json_object, or none (in the prompt only).")]
Images = Annotated[bool, typer.Option(
    "--images/--no-images", rich_help_panel=PANEL,
    help="Send the camera image with each request (default); --no-images for a text-only "
         "model: the objects list and a scene description in words instead.")]
Temperature = Annotated[float | None, typer.Option(
    "--temperature", metavar="T", min=0.0, max=2.0, rich_help_panel=PANEL,
    help="Sampling temperature of a remote model (default: the model's).")]
LlmSeed = Annotated[int | None, typer.Option(
    "--llm-seed", metavar="N", min=0, rich_help_panel=PANEL,
    help="Sampling seed of a remote model that takes one (not the layout --seed).")]
MaxTokens = Annotated[int | None, typer.Option(
    "--max-tokens", metavar="N", min=16, rich_help_panel=PANEL,
    help="Room for each answer, tokens (default: the server's); a cut answer is asked "
         "again with more.")]
ApiKeyEnv = Annotated[str | None, typer.Option(
    "--api-key-env", metavar="NAME", rich_help_panel=PANEL,
    help="Environment variable holding the API key. An openai-compatible server gets a "
         "key only this way: never OPENAI_API_KEY unless you name it here.")]
EpisodeTimeout = Annotated[float | None, typer.Option(
    "--episode-timeout", metavar="S", min=1.0, rich_help_panel=PANEL,
    help="Wall-clock limit of the episode, s (default 3600): no model call after it.")]
#: The options only a remote backend takes (flag -> its field in ModelChoice).
REMOTE_FLAGS = {"--timeout": "timeout_s", "--retries": "retries",
                "--temperature": "temperature", "--llm-seed": "llm_seed",
                "--max-tokens": "max_tokens", "--api-key-env": "api_key_env",
                "--schema-mode": "schema_mode"}


@dc.dataclass(frozen=True)
class ModelChoice:
    """The language-model options as given on the command line."""

    llm: str = "reference"
    model: str | None = None
    vertex_project: str | None = None
    vertex_location: str | None = None
    timeout_s: float | None = None
    retries: int | None = None
    schema_mode: str | None = None
    images: bool = True
    temperature: float | None = None
    llm_seed: int | None = None
    max_tokens: int | None = None
    api_key_env: str | None = None

    @property
    def kind(self) -> str:
        return self.llm.strip().partition(":")[0]

    def backend_options(self) -> dict[str, Any]:
        """Options for the backend's constructor, after checking they fit together (exits
        with one line naming the flag otherwise)."""
        vertex = {"vertex_project": self.vertex_project,
                  "vertex_location": self.vertex_location}
        given = [f"--{name.replace('_', '-')}" for name, value in vertex.items() if value]
        if given and self.llm.strip() != "gemini":
            fail(f"{' and '.join(given)} {'are' if len(given) > 1 else 'is'} for --llm "
                 f"gemini (Vertex AI), not --llm {self.llm}")
        if len(given) == 1:
            missing = "--vertex-location" if self.vertex_project else "--vertex-project"
            fail(f"Gemini on Vertex AI needs both --vertex-project and --vertex-location; "
                 f"{missing} is missing")
        if self.llm.strip() == "gemini" and not given and not self.api_key_env and not any(
                os.environ.get(name) for name in API_KEY_VARIABLES):
            fail(f"--llm gemini needs an API key in {' or '.join(API_KEY_VARIABLES)}, or "
                 "Vertex AI: --vertex-project PROJECT --vertex-location REGION")
        return {name: value for name, value in vertex.items() if value}

    def settings(self) -> ModelSettings:
        """The settings the client is built from, after checking the flags fit the backend
        (exits with one line naming the flag otherwise)."""
        vertex = self.backend_options()
        if self.kind in ("reference", "replay"):
            given = [flag for flag, field in REMOTE_FLAGS.items()
                     if getattr(self, field) is not None]
            if given:
                fail(f"{', '.join(given)} {'are' if len(given) > 1 else 'is'} for remote "
                     f"models, not --llm {self.llm.strip()}")
        if self.schema_mode is not None:
            if self.kind not in ("openai", "openai-compatible"):
                fail(f"--schema-mode is for --llm openai or openai-compatible, not --llm "
                     f"{self.llm.strip()}")
            if self.schema_mode not in SCHEMA_MODES:
                fail(f"--schema-mode must be one of {', '.join(SCHEMA_MODES)}; got "
                     f"{self.schema_mode!r}")
        if self.llm_seed is not None and self.kind == "anthropic":
            fail("--llm-seed: Claude takes no sampling seed")
        return ModelSettings(llm=self.llm.strip(), model=self.model, timeout_s=self.timeout_s,
                             retries=self.retries, schema_mode=self.schema_mode,
                             images=self.images, temperature=self.temperature,
                             seed=self.llm_seed, max_tokens=self.max_tokens,
                             api_key_env=self.api_key_env, **vertex)

    def client(self, seed: int) -> LLMClient:
        """The client (a RecordingClient); bad input ends the command with one line."""
        settings = self.settings()
        spec = settings.llm
        try:
            return settings.client(seed)
        except OSError as error:  # a replay file that is missing, a folder, unreadable
            fail(f"--llm {spec}: {describe_error(error)}")
        except UnicodeDecodeError:
            fail(f"--llm {spec}: not a JSON Lines file of model calls (it is not text)")
        except (ValueError, ImportError) as error:
            fail(str(error))


def check_server_or_exit(client: LLMClient) -> str:
    """The start-up check of the model's server (see llm.server_check); a failure ends the
    command with one line and exit code 3."""
    try:
        return check_client(client)
    except LLMError as error:
        fail(str(error), code=MODEL_FAILURE)
