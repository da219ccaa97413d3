"""Warm-up of the compiled core: compiled once per process before the first plan,
cached on disk in a folder per version of the compiled sources."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
from pathlib import Path

import rearrangement_planner
from rearrangement_planner.planning.requests import warmup


def test_the_core_is_warmed_up_once_before_the_first_plan():
    """The session fixture warmed it up; a second call (as `plan_scene` and the node make) does
    nothing, and the first call's time stays on record."""
    assert warmup.compile_seconds() is not None
    assert warmup.warm_up() == 0.0


def test_the_cache_folder_follows_the_compiled_sources(monkeypatch, tmp_path):
    """Numba keys its cache by each function's own file; the package keys the whole cache
    folder by the compiled modules' sources, so editing one kernel recompiles its callers."""
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    first = rearrangement_planner._numba_cache_dir()
    assert Path(first).is_dir() and Path(first).parent == tmp_path / "rearrangement_planner"
    real = Path.read_bytes

    def edited(path: Path) -> bytes:
        data = real(path)
        return data + b"\n# edited\n" if path.name == "kernels.py" else data

    monkeypatch.setattr(Path, "read_bytes", edited)
    assert rearrangement_planner._numba_cache_dir() != first


def test_an_unwritable_cache_home_falls_back_to_the_temp_folder(monkeypatch, tmp_path):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "home"))
    real = Path.mkdir

    def refuse(path: Path, *args, **kwargs):
        if str(path).startswith(str(tmp_path / "home")):
            raise PermissionError(13, "Permission denied", str(path))
        return real(path, *args, **kwargs)

    monkeypatch.setattr(Path, "mkdir", refuse)
    folder = rearrangement_planner._numba_cache_dir()
    assert Path(folder).name.startswith("rearrangement_planner-numba-")
    assert Path(folder).is_dir()


def test_no_plan_compiles_anything_after_the_warm_up():
    """Every compiled entry point the planners reach was compiled by `warm_up`, with the
    argument types they pass: in a fresh interpreter, a plan of each planner (with
    shortcutting) after `warm_up` adds no compiled signature, so no plan's time includes the
    compiler. And every signature takes writable arrays only: the kernels pass the arrays they
    make to each other, and a read-only argument from Python (a State's) compiled the whole
    physics step a second time, half a minute of a fresh clone's first plan. (A subprocess: in
    this one, earlier tests may have compiled them already.)"""
    script = textwrap.dedent("""
        import gc, json
        from numba.core import types
        from numba.core.registry import CPUDispatcher
        from rearrangement_planner.planning.requests.warmup import warm_up
        from rearrangement_planner.physics.validation import load_scene
        from rearrangement_planner.planning import PCRRTOptions, PlanRequest, plan_scene
        from rearrangement_planner.planning.requests.shortcut import ShortcutOptions

        def signatures():
            return {f"{d.py_func.__module__}.{d.py_func.__name__}": len(d.signatures)
                    for d in gc.get_objects() if isinstance(d, CPUDispatcher)
                    and d.py_func.__module__.startswith("rearrangement_planner")}

        warm_up()
        before = signatures()
        for scene, planner in (("easy_push", "pc-rrt"), ("default", "static-rrt"),
                               ("easy_push", "darrt")):
            plan_scene(PlanRequest.first_plan(load_scene(scene), planner,
                                              PCRRTOptions(max_iterations=60),
                                              shortcut=ShortcutOptions(5.0, 5)))
        after = signatures()

        def read_only(t):
            if isinstance(t, types.Array):
                return not t.mutable
            return isinstance(t, types.BaseTuple) and any(read_only(x) for x in t.types)

        print(json.dumps([{name: [before.get(name, 0), count] for name, count in after.items()
                           if count != before.get(name, 0)},
                          sorted(d.py_func.__name__ for d in gc.get_objects()
                                 if isinstance(d, CPUDispatcher)
                                 and d.py_func.__module__.startswith("rearrangement_planner")
                                 and any(read_only(t) for sig in d.signatures for t in sig))]))
        """)
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          timeout=600, check=True)
    added, read_only = json.loads(done.stdout.strip().splitlines()[-1])
    assert added == {}
    assert read_only == []
