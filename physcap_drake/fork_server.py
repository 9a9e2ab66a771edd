"""The program's fork server: one process that imports PRELOADED once, from which the
emulated arm's processes and the evaluation's workers start as forks.

Design notes: docs/design/physcap_drake.md.
"""

from __future__ import annotations

import io
import multiprocessing
import multiprocessing.context
import os
from multiprocessing import forkserver, popen_forkserver, reduction, spawn, util

#: What the server imports before it forks anything: an emulated arm's process and its world
#: (Drake), and an evaluation worker's episode stack.
PRELOADED = (
    "physcap_drake.can.child_process",
    "physcap_drake.piper_emulator.emulator_process",
    "physcap_drake.piper_emulator.emulator",
    "physcap_drake.piper_emulator.paced_world",
    "physcap_drake.emulated_world",
    "physcap_drake.eval.runner",
)
#: What multiprocessing hands a child to import the parent's main module (or run its script)
#: again.
MAIN_MODULE_KEYS = ("init_main_from_name", "init_main_from_path")


def fork_context() -> multiprocessing.context.BaseContext:
    """multiprocessing's forkserver start method with PRELOADED; every user of the server in
    this program takes it from here, so the server is the same whoever starts it."""
    context = multiprocessing.get_context("forkserver")
    context.set_forkserver_preload(list(PRELOADED))
    return context


class ForkedProcess(multiprocessing.context.ForkServerProcess):
    """A multiprocessing Process forked from the server whose child does not import the
    parent's main module again: its target lives in a preloaded module, and a user's script
    that starts an emulated arm is not run a second time in it."""

    @staticmethod
    def _Popen(process_obj):  # noqa: N802 (multiprocessing's name)
        fork_context()
        return _PopenWithoutMain(process_obj)


class _PopenWithoutMain(popen_forkserver.Popen):
    def _launch(self, process_obj) -> None:
        # The forkserver start of multiprocessing.popen_forkserver, minus the main module.
        prepared = {key: value for key, value in
                    spawn.get_preparation_data(process_obj._name).items()
                    if key not in MAIN_MODULE_KEYS}
        payload = io.BytesIO()
        multiprocessing.context.set_spawning_popen(self)
        try:  # descriptors among the arguments are collected for the server here
            reduction.dump(prepared, payload)
            reduction.dump(process_obj, payload)
        finally:
            multiprocessing.context.set_spawning_popen(None)
        self.sentinel, data = forkserver.connect_to_new_process(self._fds)
        parent_alive = os.dup(data)  # the child's sign that this process lives
        self.finalizer = util.Finalize(self, util.close_fds, (parent_alive, self.sentinel))
        with open(data, "wb", closefd=True) as pipe:
            pipe.write(payload.getbuffer())
        self.pid = forkserver.read_signed(self.sentinel)
