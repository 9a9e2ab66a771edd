"""The `physcap` console command: picks the memory allocator, then runs the command line.

Kept apart from `cli` so that the process can start itself again with TCMalloc
(`allocator.use_tcmalloc`) before it imports Drake and the commands.
"""

from __future__ import annotations

from physcap_drake.allocator import use_tcmalloc


def main() -> None:
    """The console command's entry point (see pyproject.toml)."""
    use_tcmalloc()
    from physcap_drake.cli import main as run_command_line

    run_command_line()
