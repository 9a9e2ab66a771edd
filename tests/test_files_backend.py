"""The files backend: each request is written out in full, and the answer file written beside
it is the model's answer."""

from __future__ import annotations

import json
import threading

import cv2
import numpy as np
import pytest

from physcap_drake.agent.llm.base import LLMRequest, LLMTimeout, innermost
from physcap_drake.agent.llm.factory import make_llm
from physcap_drake.agent.llm.files_backend import FilesClient
from physcap_drake.agent.schemas import CoderAnswer
from physcap_drake.agent.structured_call import ask_structured


def _jpeg(width: int, height: int) -> bytes:
    image = np.zeros((height, width, 3), np.uint8)
    image[:, : width // 2] = (0, 0, 255)  # left half red (BGR)
    return cv2.imencode(".jpg", image)[1].tobytes()


REQUEST = LLMRequest(role="coder", system="You write code.", prompt="# Task\nWeigh the can.",
                     images=(_jpeg(64, 48),), json_schema=CoderAnswer.model_json_schema())
ANSWER = json.dumps({"thought": "weigh it", "code": "home_pose()"})


class FakeTime:
    """A clock that moves only when the client sleeps."""

    def __init__(self):
        self.now = 0.0

    def clock(self) -> float:
        return self.now

    def sleep(self, seconds: float) -> None:
        self.now += seconds


def test_a_request_is_written_in_full_and_the_answer_file_is_the_answer(tmp_path):
    waited = []

    def answer_when_asked(path):
        waited.append(path)
        path.write_text(ANSWER)

    client = FilesClient(tmp_path, on_wait=answer_when_asked)
    response = client.complete(REQUEST)
    folder = tmp_path / "000_coder"
    assert waited == [folder / "answer.txt"]
    assert response.text == ANSWER and response.model == "files"
    assert (folder / "system.md").read_text() == "You write code.\n"
    assert (folder / "user.md").read_text() == "# Task\nWeigh the can.\n"
    assert json.loads((folder / "schema.json").read_text()) == REQUEST.json_schema
    image = cv2.imread(str(folder / "image_0.png"))
    assert image.shape == (48, 64, 3)
    assert image[24, 5, 2] > 200 and image[24, 60, 2] < 50  # red on the left, as sent
    second = client.write_request(REQUEST)
    assert second.name == "001_coder"


def test_no_answer_within_the_timeout_names_the_file_awaited(tmp_path):
    time = FakeTime()
    client = FilesClient(tmp_path, timeout_s=5.0, clock=time.clock, sleep=time.sleep,
                         on_wait=lambda path: None)
    with pytest.raises(LLMTimeout, match=r"no answer in .*000_coder/answer.txt after 5 s"):
        client.complete(REQUEST)
    assert 5.0 < time.now <= 6.0  # gave up just after the timeout, not before


def test_an_answer_written_later_by_someone_else_is_picked_up(tmp_path):
    client = make_llm(f"files:{tmp_path}", timeout_s=30.0)
    assert isinstance(innermost(client), FilesClient)
    answer = tmp_path / "000_coder" / "answer.txt"
    player = threading.Thread(target=lambda: _answer_when_written(answer))
    player.start()
    parsed, _ = ask_structured(client, REQUEST, CoderAnswer, repairs=0)
    player.join()
    assert parsed.code == "home_pose()"


def _answer_when_written(answer) -> None:
    import time
    deadline = time.monotonic() + 20.0
    while not (answer.parent / "user.md").is_file():
        assert time.monotonic() < deadline, "the request was never written"
        time.sleep(0.05)
    answer.write_text("Here it is:\n" + ANSWER)


def test_the_spec_needs_a_folder_and_takes_only_a_timeout(tmp_path):
    with pytest.raises(ValueError, match="needs a folder"):
        make_llm("files:")
    with pytest.raises(ValueError, match="does not take option"):
        make_llm(f"files:{tmp_path}", temperature=0.2)
    with pytest.raises(ValueError, match="must be positive"):
        make_llm(f"files:{tmp_path}", timeout_s=0.0)
