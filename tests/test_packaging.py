"""The wheel carries models/, stations/ and agents/, and the package finds them there."""

from __future__ import annotations

import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

pytestmark = pytest.mark.xdist_group("test_packaging")

ROOT = Path(__file__).resolve().parents[1]

FIND_DATA = """
import physcap_drake, physcap_drake.resources as r
from physcap_drake.scenario import load_scenario
from physcap_drake.station import MakeStation
print(physcap_drake.__file__)
print(r.models_dir()); print(r.stations_dir()); print(r.agents_dir())
MakeStation(load_scenario(r.stations_dir() / "piper_table.yaml"))
print("station built")
"""


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("wheel")
    subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation",
                    "-q", "-w", str(out), str(ROOT)], check=True)
    return next(out.glob("physcap_drake-*.whl"))


def test_wheel_contains_the_data_folders(wheel):
    names = set(zipfile.ZipFile(wheel).namelist())
    for expected in ("physcap_drake/_data/models/piper/piper_arm.sdf",
                     "physcap_drake/_data/models/piper/piper_100mm.dmd.yaml",
                     "physcap_drake/_data/stations/piper_table.yaml",
                     "physcap_drake/_data/agents/README.md",
                     "physcap_drake/station/sim_station.py"):
        assert expected in names, expected
    assert not any(name.startswith("tests/") for name in names)


def test_installed_wheel_finds_its_data(wheel, tmp_path):
    site = tmp_path / "site"
    zipfile.ZipFile(wheel).extractall(site)
    result = subprocess.run([sys.executable, "-c", FIND_DATA], cwd=tmp_path, text=True,
                            capture_output=True, env={"PYTHONPATH": str(site), "PATH": "/usr/bin"})
    assert result.returncode == 0, result.stderr
    lines = result.stdout.splitlines()
    assert lines[0].startswith(str(site))
    for line, name in zip(lines[1:4], ("models", "stations", "agents"), strict=True):
        assert line == str(site / "physcap_drake" / "_data" / name)
    assert lines[4] == "station built"
