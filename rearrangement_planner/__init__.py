"""Nonprehensile whole-arm rearrangement planning: the ROS-free core."""

from __future__ import annotations

import hashlib
import os
import tempfile
from pathlib import Path

COMPILED_MODULES = ("physics/kernels.py", "physics/pushing.py", "physics/step.py",
                    "planning/machinery/manifold.py", "planning/machinery/propagation.py",
                    "planning/requests/robustness.py", "planning/machinery/tree.py")
"""The modules with Numba-compiled functions (`@njit(cache=True)`)."""


def _numba_cache_dir() -> str:
    """A Numba cache folder per version of the compiled modules' sources. Numba keys a cached
    function by its own file only: a kernel edited in one module would leave its callers'
    cached machine code in other modules stale. One folder per source hash makes every change
    recompile (once; about a minute on first use)."""
    root = Path(__file__).parent
    digest = hashlib.sha256()
    for name in COMPILED_MODULES:
        digest.update((root / name).read_bytes())
    name = f"numba-{digest.hexdigest()[:16]}"
    base = Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "rearrangement_planner"
    for folder in (base / name, Path(tempfile.gettempdir()) / f"rearrangement_planner-{name}"):
        try:
            folder.mkdir(parents=True, exist_ok=True)
        except OSError:
            continue
        if os.access(folder, os.W_OK):
            return str(folder)
    return str(base / name)       # not writable: Numba then compiles without caching


# Before any module imports numba, which reads its configuration once on import.
os.environ.setdefault("NUMBA_CACHE_DIR", _numba_cache_dir())
