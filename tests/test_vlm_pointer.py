"""The VLM pointer: answer parsing for Gemini- and Molmo-style points, and the whole path
from a model's answer to a grasp point."""

from __future__ import annotations

import numpy as np
import pytest
from perception_inputs import module

from physcap_drake.app.episode import make_episode
from physcap_drake.perception.object_locator import ObjectLocator
from physcap_drake.perception.offline_pointer import PointingError
from physcap_drake.perception.vlm_pointer import VlmPointer, parse_point
from physcap_drake.station import ports

W, H = 640, 360


@pytest.mark.parametrize(("answer", "pixel"), [
    ('[{"point": [500, 250], "label": "red can"}]', (160, 180)),
    ('```json\n[{"point": [250, 500], "label": "cup"}]\n```', (320, 90)),
    ("[1000, 0]", (0, 359)),
    ('The can is here: <point x="25.0" y="50.0" alt="red can">red can</point>', (160, 180)),
    ('<points x1="10" y1="20" x2="30" y2="40" alt="cans">cans</points>', (64, 72)),
])
def test_answers_are_parsed(answer, pixel):
    assert parse_point(answer, W, H) == pixel


@pytest.mark.parametrize("answer", [
    "I cannot see a red can.", '[{"label": "red can"}]', "[1200, 10]", "[1, 2, 3]",
    '<point alt="can">can</point>', "[{oops",
])
def test_bad_answers_are_clear_errors(answer):
    with pytest.raises(PointingError):
        parse_point(answer, W, H)


def test_a_model_answer_becomes_a_grasp_point():
    episode = make_episode("identify_empty_can", 0)
    station = episode.robot.station
    context = station.GetMyContextFromRoot(episode.api.simulator.get_context())
    rgb = station.GetOutputPort(ports.CAMERA_RGB).Eval(context).data
    label = station.GetOutputPort(ports.CAMERA_LABEL).Eval(context).data
    target = episode.instance.object("green can")
    pixel = module(episode).pointer.point(label, "green can").pixel  # a "perfect" model
    requests = []

    def ask(jpeg: bytes, prompt: str) -> str:
        requests.append((jpeg, prompt))
        return f'[{{"point": [{1000 * pixel[1] / H:.1f}, {1000 * pixel[0] / W:.1f}]}}]'

    pointed = VlmPointer(ask).point(rgb, "green can")
    jpeg, prompt = requests[0]
    assert jpeg[:2] == b"\xff\xd8" and "green can" in prompt and "[y, x]" in prompt
    assert np.hypot(pointed[0] - pixel[0], pointed[1] - pixel[1]) <= 1.5
    seen = ObjectLocator.object_at(pointed, list(episode.look().objects))
    assert seen.name == "green can"
    grasp = seen.grasp_point
    assert np.linalg.norm(grasp[:2] - np.array(target.xy)) < 0.015
    assert grasp[2] == pytest.approx(0.065, abs=0.005)


def test_get_object_pose_works_with_a_vlm_pointer():
    episode = make_episode("pick_ripe_avocado", 0)
    station = episode.robot.station
    context = station.GetMyContextFromRoot(episode.api.simulator.get_context())
    label = station.GetOutputPort(ports.CAMERA_LABEL).Eval(context).data
    offline = module(episode).pointer

    def ask(jpeg: bytes, prompt: str) -> str:  # a model that points where the mask centre is
        phrase = prompt.split("Point at the ", 1)[1].split(" in this image", 1)[0]
        u, v = offline.point(label, phrase).pixel
        return f'<point x="{100 * (u + 0.5) / W:.2f}" y="{100 * (v + 0.5) / H:.2f}">x</point>'

    episode.api.use_locator(ObjectLocator(VlmPointer(ask)))
    for obj in episode.instance.objects:
        grasp = episode.api.get_object_pose(obj.visible.name)
        assert np.linalg.norm(grasp[:2] - np.array(obj.xy)) < 0.015, obj.visible.name


def test_any_image_backend_can_serve_the_pointer():
    """pointer_ask sends the JPEG and the question as a recorded "pointer" request."""
    from physcap_drake.agent.llm import RecordingClient
    from physcap_drake.agent.llm.base import LLMResponse
    from physcap_drake.agent.llm.pointer_ask import pointer_ask

    class Gemini:
        name, model = "fake-gemini", "fake-1"

        def complete(self, request):
            assert request.role == "pointer" and len(request.images) == 1
            assert request.images[0][:2] == b"\xff\xd8"  # a JPEG
            return LLMResponse('```json\n[{"point": [500, 250], "label": "red can"}]\n```',
                               self.model)

    client = RecordingClient(Gemini())
    rgb = np.zeros((360, 640, 3), dtype=np.uint8)
    assert VlmPointer(pointer_ask(client)).point(rgb, "red can") == (160, 180)
    assert client.records[0].role == "pointer" and "red can" in client.records[0].prompt
