"""What a perception module's input ports read from an episode's station now (test helper)."""

from __future__ import annotations

from physcap_drake.station import ports


def station_inputs(episode) -> dict:
    """{port name: value} of the episode perception's input ports: images as arrays, the
    measured joints (rad) as they are."""
    perception, station = episode.api.locator.perception, episode.robot.station
    context = station.GetMyContextFromRoot(episode.api.simulator.get_context())
    images = {port: station.GetOutputPort(port).Eval(context) for port in
              perception.input_ports}
    return {port: value if port == ports.ARM_POSITION_MEASURED else value.data
            for port, value in images.items()}
