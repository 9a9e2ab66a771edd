"""The `physcap` console command: limits NumPy's BLAS threads, picks the memory allocator,
then runs the command line.

Kept apart from `cli` so that both happen before anything imports NumPy or Drake: OpenBLAS
reads its thread count when it is loaded (`blas_threads.limit`), and the process starts
itself again with TCMalloc (`allocator.use_tcmalloc`).
"""

from __future__ import annotations

import sys

from physcap_drake import blas_threads
from physcap_drake.allocator import use_tcmalloc


def main() -> None:
    """The console command's entry point (see pyproject.toml)."""
    blas_threads.limit()
    use_tcmalloc()
    from physcap_drake.commands import emulate

    if emulate.alone(sys.argv[1:]):  # an emulated arm alone starts in a third of the time
        emulate.emulate_alone(sys.argv[2:])
    from physcap_drake.cli import main as run_command_line

    run_command_line()
