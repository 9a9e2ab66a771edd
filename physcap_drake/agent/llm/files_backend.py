"""FilesClient: a "model" played by whoever answers request files in a folder (a person, or
another model that sees only the requests).

Design notes: docs/agent_files_backend.md.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np

from physcap_drake.agent.llm.base import LLMRequest, LLMResponse, LLMTimeout

MODEL = "files"
#: How often the answer file is looked for, s.
POLL_S = 0.5


class FilesClient:
    """Writes request N into `folder` as NNN_<role>/ (system.md, user.md, schema.json,
    image_K.png) and waits until NNN_<role>/answer.txt appears; its text is the answer.
    `timeout_s`: how long to wait for one answer (LLMTimeout names the file after it)."""

    name = "files"

    def __init__(self, folder: str | Path, timeout_s: float = 3600.0,
                 clock: Callable[[], float] = time.monotonic,
                 sleep: Callable[[float], None] = time.sleep,
                 on_wait: Callable[[Path], None] | None = None):
        if not timeout_s > 0:
            raise ValueError(f"the files backend's timeout must be positive, got {timeout_s:g} s")
        self.folder = Path(folder)
        self.folder.mkdir(parents=True, exist_ok=True)
        self.model = MODEL
        self._timeout_s = float(timeout_s)
        self._clock, self._sleep = clock, sleep
        self._on_wait = on_wait or _say_waiting
        self._count = len(list(self.folder.glob("[0-9][0-9][0-9]_*")))

    def complete(self, request: LLMRequest) -> LLMResponse:
        started = self._clock()
        folder = self.write_request(request)
        answer = folder / "answer.txt"
        self._on_wait(answer)
        while not answer.is_file():
            if self._clock() - started > self._timeout_s:
                raise LLMTimeout(f"no answer in {answer} after {self._timeout_s:g} s "
                                 "(raise --timeout to wait longer)")
            self._sleep(POLL_S)
        text = answer.read_text()
        return LLMResponse(text, MODEL, input_tokens=len(request.prompt.split()),
                           output_tokens=len(text.split()),
                           latency_s=self._clock() - started)

    def write_request(self, request: LLMRequest) -> Path:
        """The folder of the next request, written in full (what the model would see)."""
        folder = self.folder / f"{self._count:03d}_{request.role}"
        self._count += 1
        folder.mkdir()
        (folder / "system.md").write_text(request.system + "\n")
        (folder / "user.md").write_text(request.prompt + "\n")
        if request.json_schema is not None:
            (folder / "schema.json").write_text(json.dumps(request.json_schema, indent=1))
        for index, jpeg in enumerate(request.images):
            image = cv2.imdecode(np.frombuffer(jpeg, np.uint8), cv2.IMREAD_COLOR)
            if image is None:
                raise ValueError(f"image {index} of the {request.role} request is not a JPEG")
            cv2.imwrite(str(folder / f"image_{index}.png"), image)
        return folder


def _say_waiting(answer: Path) -> None:
    print(f"[files model] waiting for {answer}", flush=True)
