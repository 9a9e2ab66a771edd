"""The threads of the BLAS library under NumPy in a `physcap` process: one, unless asked.

Design notes: docs/design/physcap_drake.md.
"""

from __future__ import annotations

import ctypes
import os
from collections.abc import MutableMapping

#: The environment variable OpenBLAS reads its thread count from.
VARIABLE = "OPENBLAS_NUM_THREADS"
#: The thread count `physcap` asks for when the user has not set one.
DEFAULT = "1"
#: What the OpenBLAS builds NumPy ships call their thread-count getter (SciPy's 64-bit
#: interface build since NumPy 2; a plain OpenBLAS before).
_GETTERS = ("scipy_openblas_get_num_threads64_", "openblas_get_num_threads64_",
            "openblas_get_num_threads")


def limit(environ: MutableMapping[str, str] = os.environ) -> str:
    """Sets OPENBLAS_NUM_THREADS in `environ` to DEFAULT unless it is set; returns the value
    in effect. Call it before NumPy is imported (later, it only reaches child processes)."""
    return environ.setdefault(VARIABLE, DEFAULT)


def in_use(maps_path: str = "/proc/self/maps") -> int | None:
    """The number of threads NumPy's OpenBLAS runs with in this process (imports NumPy), or
    None where no OpenBLAS with a known getter is loaded (e.g. a NumPy built on another
    BLAS, or no /proc)."""
    import numpy  # noqa: F401  (loads its BLAS)

    try:
        with open(maps_path) as maps:
            paths = {fields[-1] for fields in map(str.split, maps)
                     if len(fields) == 6 and "openblas" in fields[-1] and ".so" in fields[-1]}
    except OSError:
        return None
    for path in sorted(paths, key=lambda p: "numpy" not in p):  # NumPy's own first
        library = ctypes.CDLL(path)
        for getter in _GETTERS:
            function = getattr(library, getter, None)
            if function is not None:
                return int(function())
    return None
