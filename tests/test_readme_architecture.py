"""The README's architecture section says what the code is: its list of the agent episode's
connections is the diagram `make_episode(..., with_agent=True)` builds, and its layer list
is the order tests/test_layers.py enforces."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from test_layers import LAYERS

from physcap_drake.app.episode import make_episode

README = Path(__file__).resolve().parents[1] / "README.md"
ARROW = re.compile(r"^(\S+) ──(.+?)──> (.+)$")


def _section(title: str) -> str:
    text = README.read_text()
    start = text.index(f"## {title}\n")
    return text[start:text.index("\n## ", start + 1)]


def _code_block(section: str) -> list[str]:
    start = section.index("```\n") + 4
    return section[start:section.index("```", start)].strip().splitlines()


def readme_connections() -> set[tuple[str, str, str, str]]:
    """(source system, output port, destination system, input port) for every connection
    the README's chains name. A chain `a ──p──> b ──q──> c` connects a.p to b.p and b.q to
    c.q (ports of a connection share their name, as everywhere on this diagram)."""
    edges = set()
    for line in _code_block(_section("Architecture")):
        hops = re.split(r" (──.+?──>) ", line)
        assert len(hops) >= 3 and len(hops) % 2 == 1, f"not a chain: {line!r}"
        for at in range(0, len(hops) - 2, 2):
            sources = [hops[at]]
            ports = [p.strip() for p in hops[at + 1][2:-3].split(",")]
            targets = [t.strip() for t in hops[at + 2].split(",")]
            for source in sources:
                for port in ports:
                    for target in targets:
                        edges.add((source, port, target, port))
    return edges


def built_connections(diagram) -> set[tuple[str, str, str, str]]:
    """The same for a built diagram, with the gripper command selector's inputs named as
    the README names them (the selector prefixes each input with whose command it is)."""
    edges = set()
    for (to_system, to_index), (from_system, from_index) in diagram.connection_map().items():
        to_port = to_system.get_input_port(to_index).get_name()
        to_port = re.sub(r"^(executor|probe)\.", "", to_port)
        edges.add((from_system.get_name(), from_system.get_output_port(from_index).get_name(),
                   to_system.get_name(), to_port))
    return edges


@pytest.fixture(scope="module")
def episode_diagram():
    return make_episode("identify_empty_can", 0, with_agent=True).robot.diagram


def test_every_connection_of_the_agent_episode_is_in_the_readme(episode_diagram):
    diagram = episode_diagram
    built, written = built_connections(diagram), readme_connections()
    assert built - written == set(), "connections missing from the README's architecture"
    assert written - built == set(), "the README's architecture names connections the " \
                                     "diagram does not have"


def test_the_exported_status_is_the_mass_probes(episode_diagram):
    diagram = episode_diagram
    exported = [diagram.get_output_port(i).get_name() for i in range(diagram.num_output_ports())]
    assert exported == ["robot.status"]


def test_the_readme_lists_the_enforced_layers_in_order():
    section = _section("Architecture")
    block = section[section.index("<!-- layers -->"):section.index("<!-- /layers -->")]
    written = [tuple(name.strip(" `") for name in line.split(". ", 1)[1].split(","))
               for line in block.splitlines() if re.match(r"^\d+\. ", line)]
    assert written == list(LAYERS)
