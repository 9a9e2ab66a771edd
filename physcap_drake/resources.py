"""Locates the project's data folders (`models/`, `stations/`, `agents/`).

From a source checkout (editable install or plain PYTHONPATH) the folders sit next to the
package; an installed wheel carries copies under `physcap_drake/_data/`. Both are found the
same way, so scenario files and model URLs work from either.
"""

from functools import cache
from pathlib import Path

from pydrake.multibody.parsing import PackageMap

#: The package name model URLs use: ``package://physcap_models/piper/piper_arm.sdf``.
MODELS_PACKAGE = "physcap_models"

_PACKAGE_DIR = Path(__file__).resolve().parent


def _data_dir(name: str) -> Path:
    for candidate in (_PACKAGE_DIR.parent / name, _PACKAGE_DIR / "_data" / name):
        if candidate.is_dir():
            return candidate
    raise FileNotFoundError(
        f"physcap-drake data folder '{name}/' is missing: looked in "
        f"{_PACKAGE_DIR.parent / name} (checkout) and {_PACKAGE_DIR / '_data' / name} (wheel)"
    )


def models_dir() -> Path:
    """The folder of our SDF models (PiPER, table, tray, objects)."""
    return _data_dir("models")


def stations_dir() -> Path:
    """The folder of scenario YAML files."""
    return _data_dir("stations")


def agents_dir() -> Path:
    """The folder of prompt templates and agent-variant configs."""
    return _data_dir("agents")


@cache
def _package_paths() -> tuple[tuple[str, str], ...]:
    return ((MODELS_PACKAGE, str(models_dir())),)


def add_model_packages(package_map: PackageMap) -> None:
    """Registers ``package://physcap_models/...`` with a parser's package map."""
    for name, path in _package_paths():
        if not package_map.Contains(name):
            package_map.Add(name, path)


def make_package_map() -> PackageMap:
    """A fresh package map that resolves our model URLs."""
    package_map = PackageMap()
    add_model_packages(package_map)
    return package_map
