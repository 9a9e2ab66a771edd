"""NumPy's BLAS threads in a `physcap` process: one unless the user set a number, what
`physcap --version` reports, and how the count is read from the process."""

from __future__ import annotations

import os
import subprocess
import sys

from physcap_drake import blas_threads


def _version(**extra: str) -> str:
    environ = {k: v for k, v in os.environ.items() if k != blas_threads.VARIABLE}
    done = subprocess.run([sys.executable, "-m", "physcap_drake", "--version"],
                          env={**environ, **extra}, capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0, done.stderr
    return done.stdout.strip()


def test_limit_asks_for_one_thread_and_keeps_a_value_the_user_set():
    environ: dict[str, str] = {}
    assert blas_threads.limit(environ) == "1"
    assert environ == {"OPENBLAS_NUM_THREADS": "1"}
    environ = {"OPENBLAS_NUM_THREADS": "4"}
    assert blas_threads.limit(environ) == "4"
    assert environ == {"OPENBLAS_NUM_THREADS": "4"}


def test_physcap_runs_numpys_blas_on_one_thread_unless_told_otherwise():
    assert _version().endswith("BLAS threads 1)")
    assert _version(OPENBLAS_NUM_THREADS="2").endswith("BLAS threads 2)")


def test_the_count_is_unknown_where_no_openblas_is_mapped(tmp_path):
    maps = tmp_path / "maps"
    maps.write_text("7f00-7f10 r-xp 0 08:01 1 /usr/lib/x86_64-linux-gnu/libc.so.6\n"
                    "7f10-7f20 r-xp 0 08:01 2 /usr/lib/x86_64-linux-gnu/libblas.so.3\n")
    assert blas_threads.in_use(str(maps)) is None
    assert blas_threads.in_use(str(tmp_path / "missing")) is None


def test_the_count_is_read_from_the_openblas_numpy_loaded():
    count = blas_threads.in_use()
    assert count is not None and count >= 1
    assert count == 1 or os.environ.get(blas_threads.VARIABLE) != "1"
