"""Running the evaluation grid on a Ray cluster (`physcap eval --ray [ADDRESS]`).

Design notes: docs/design/eval.md.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import ray

from physcap_drake.agent.llm.factory import ModelSettings
from physcap_drake.app.episode_folder import (
    ERROR_FILE,
    MESHCAT_FILE,
    SUMMARY_FILE,
    read_summary,
    record_episode,
)
from physcap_drake.eval.grid import EpisodeSpec
from physcap_drake.eval.ray_models import episode_client
from physcap_drake.eval.runner import EPISODES_PER_WORKER, pending

#: How often Ray reruns an episode whose worker died.
RETRIES = 3


@ray.remote(num_cpus=1, max_retries=RETRIES, max_calls=EPISODES_PER_WORKER)
def run_episode_task(spec: EpisodeSpec, llm: str | ModelSettings, model: str | None
                     ) -> dict[str, Any]:
    """Runs one episode on a Ray worker; returns {"spec", "files": {name: bytes}, "error"}."""
    client = episode_client(llm, model, spec.seed)
    options = {} if client is None else {"client": client}
    error = None
    with tempfile.TemporaryDirectory(prefix="physcap_episode_") as folder:
        try:
            record_episode(folder, spec.task, spec.seed, agent=spec.agent, llm=llm,
                           model=model, overwrite=True, **options)
        except Exception as exc:  # noqa: BLE001 - recorded like the process pool does
            error = f"{type(exc).__name__}: {exc}"
        files = {path.name: path.read_bytes() for path in Path(folder).iterdir()
                 if path.is_file()}
    return {"spec": spec, "files": files, "error": error}


def store_episode(payload: dict[str, Any], out: Path) -> dict[str, Any]:
    """Writes a task's files into the episode's folder (stale results removed first, the
    summary last and atomically); returns {"spec", "summary"} or {"spec", "error"}."""
    spec: EpisodeSpec = payload["spec"]
    folder = spec.folder(out)
    folder.mkdir(parents=True, exist_ok=True)
    for stale in (SUMMARY_FILE, ERROR_FILE, MESHCAT_FILE):
        (folder / stale).unlink(missing_ok=True)
    files = payload["files"]
    for name, data in files.items():
        if name != SUMMARY_FILE:
            (folder / name).write_bytes(data)
    if payload["error"] is not None or SUMMARY_FILE not in files:
        return {"spec": spec, "error": payload["error"] or "the episode wrote no summary"}
    partial = folder / (SUMMARY_FILE + ".partial")
    partial.write_bytes(files[SUMMARY_FILE])
    os.replace(partial, folder / SUMMARY_FILE)
    return {"spec": spec, "summary": read_summary(folder)}


def connect(address: str | None, workers: int) -> bool:
    """Connects to the cluster at `address`, or starts a local instance with `workers` CPUs
    (address None); returns whether it connected here (to disconnect at the end). A process
    already connected (ray.init called before) keeps its connection."""
    if ray.is_initialized():
        return False
    if address is None:
        ray.init(address="local", num_cpus=workers, include_dashboard=False,
                 logging_level="WARNING")
        return True
    ray.init(address=address, logging_level="WARNING")
    return True


def run_grid_on_ray(specs: list[EpisodeSpec], out: Path, *,
                    llm: str | ModelSettings = "reference",
                    model: str | None = None, address: str | None = None, workers: int = 2,
                    on_done: Callable[[dict[str, Any]], None] | None = None
                    ) -> list[dict[str, Any]]:
    """Runs the unfinished episodes of `specs` as Ray tasks and returns their results in the
    order they finished; `on_done(result)` hears each one (see `eval.runner.run_grid`)."""
    todo = pending(specs, out)
    if not todo:
        return []
    connected = connect(address, workers)
    results: list[dict[str, Any]] = []
    waiting: dict[Any, EpisodeSpec] = {}
    try:
        waiting = {run_episode_task.remote(spec, llm, model): spec for spec in todo}
        while waiting:
            ready, _ = ray.wait(list(waiting), num_returns=1)
            spec = waiting.pop(ready[0])
            try:
                result = store_episode(ray.get(ready[0]), out)
            except ray.exceptions.RayError as error:  # retries used up, or the node lost
                result = {"spec": spec, "error": f"{type(error).__name__}: {error}"}
            results.append(result)
            if on_done is not None:
                on_done(result)
    finally:
        for ref in waiting:  # interrupted: nothing half-written stays behind on our side
            ray.cancel(ref, force=True)
        if connected:
            ray.shutdown()
    return results
