"""The language-model options of the commands that run the agent, in one place.

`ModelChoice` gathers them (backend spec, model name, Gemini on Vertex AI) and builds the
client; its checks speak in the command line's own words (flags and environment variables,
not the Python API's parameter names). Add an option here: an Annotated alias for the
command's signature, a field, and its use in `backend_options`.
"""

from __future__ import annotations

import dataclasses as dc
import os
from typing import Annotated, Any

import typer

from physcap_drake.agent.llm import LLMClient, make_llm
from physcap_drake.agent.llm.factory import VALID_SPECS
from physcap_drake.agent.llm.gemini import API_KEY_VARIABLES
from physcap_drake.commands.common import describe_error, fail

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


@dc.dataclass(frozen=True)
class ModelChoice:
    """The language-model options as given on the command line."""

    llm: str = "reference"
    model: str | None = None
    vertex_project: str | None = None
    vertex_location: str | None = None

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
        if self.llm.strip() == "gemini" and not given and not any(
                os.environ.get(name) for name in API_KEY_VARIABLES):
            fail(f"--llm gemini needs an API key in {' or '.join(API_KEY_VARIABLES)}, or "
                 "Vertex AI: --vertex-project PROJECT --vertex-location REGION")
        return {name: value for name, value in vertex.items() if value}

    def client(self, seed: int) -> LLMClient:
        """The client (a RecordingClient); bad input ends the command with one line."""
        options = self.backend_options()
        spec = self.llm.strip()
        try:
            return make_llm(spec, self.model, seed=seed, **options)
        except OSError as error:  # a replay file that is missing, a folder, unreadable
            fail(f"--llm {spec}: {describe_error(error)}")
        except UnicodeDecodeError:
            fail(f"--llm {spec}: not a JSON Lines file of model calls (it is not text)")
        except (ValueError, ImportError) as error:
            fail(str(error))
