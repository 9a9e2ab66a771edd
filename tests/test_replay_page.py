"""The replay page's markup: the steps beside Meshcat's page, in order, at their times,
their text escaped (a code block's text cannot become markup)."""

from __future__ import annotations

import re

import pytest

from physcap_drake.agent.transcript import TranscriptEntry
from physcap_drake.app.replay_page import TimedEntry, replay_page

MESHCAT_PAGE = ("<html><head><title>Drake MeshCat</title></head><body>"
                "<div id=\"meshcat-pane\"></div><script>var viewer;</script></body></html>")


def test_the_steps_follow_the_meshcat_page_in_order_at_their_times():
    steps = [TimedEntry(0.008, TranscriptEntry("planner", 0, 0.0, "more is needed")),
             TimedEntry(10.1, TranscriptEntry("measurement", 0, 9.9, "red can: mass = 0.4 kg")),
             TimedEntry(10.1, TranscriptEntry("code", 1, 9.9, 'print("</pre><script>x")'))]
    page = replay_page(MESHCAT_PAGE, steps, "a <title>", "weigh & see", "success: yes")
    items = re.findall(r'<li data-t="([\d.]+)" data-kind="(\w+)">', page)
    assert items == [("0.008", "planner"), ("10.100", "measurement"), ("10.100", "code")]
    assert "robot time 9.9 s" in page and "red can: mass = 0.4 kg" in page
    assert "&lt;/pre&gt;&lt;script&gt;" in page and "</pre><script>x" not in page
    assert "a &lt;title&gt;" in page and "weigh &amp; see" in page and "success: yes" in page
    # Meshcat's own page is kept whole; the style goes in its head, the steps in its body.
    assert page.index("<style>") < page.index("</head>") < page.index('<div id="meshcat-pane">')
    assert page.index("var viewer;") < page.index('<aside id="physcap-steps">') < page.index(
        "</body>")


def test_a_page_that_is_not_meshcats_is_refused():
    with pytest.raises(ValueError, match="not a Meshcat page"):
        replay_page("<p>hello</p>", [], "t")
