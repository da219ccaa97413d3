"""Profile the compiled code with Linux perf: run `same_work.py`'s searches, then write the
perf map (/tmp/perf-PID.map) of every function Numba compiled in this process, so that
`perf report` names them instead of showing bare [JIT] addresses (docs/benchmark.md,
"Project without LAPACK"). Numba must compile afresh (code loaded from its cache has no
symbols here), so point NUMBA_CACHE_DIR at an empty folder; compilation is then most of the
samples, and the shares to compare are those of the [JIT] functions. From the checkout:

    NUMBA_CACHE_DIR=$(mktemp -d) perf record -F 999 -o perf.data \\
        python docs/benchmark/time/perf_map.py v1_s1,v2_s1 1500
    perf report -i perf.data --no-children --sort dso,sym | grep JIT
"""

import gc
import os
import runpy
import sys
from pathlib import Path

from numba.core.registry import CPUDispatcher

sys.argv = ["same_work.py", *sys.argv[1:]]
runpy.run_path(str(Path(__file__).with_name("same_work.py")), run_name="__main__")
names: dict[int, str] = {}
for dispatcher in (o for o in gc.get_objects() if isinstance(o, CPUDispatcher)):
    for compiled in dispatcher.overloads.values():
        library = compiled.library
        module = getattr(library, "_final_module", None)
        if module is None:
            continue
        for function in module.functions:
            if not function.is_declaration:
                address = library.get_pointer_to_function(function.name)
                if address:
                    names[address] = function.name
starts = sorted(names)
with open(f"/tmp/perf-{os.getpid()}.map", "w") as out:
    for start, end in zip(starts, [*starts[1:], starts[-1] + 4096], strict=True):
        out.write(f"{start:x} {min(end - start, 1 << 20):x} {names[start]}\n")
print(f"perf map: {len(starts)} compiled functions", file=sys.stderr)
