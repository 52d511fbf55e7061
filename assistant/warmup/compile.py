"""The background compile (`python -m assistant.warmup.compile`): every kernel into numba's
cache, each reported on stdout ("ready module.function") as soon as its machine code is
saved, then the cache's completion marker ("done").

Started by `lazy.start()`; runs at lowered priority so the operator's own work keeps the
faster share of the machine. The warm-up steps it runs are `CELLTEACH_WARM_STEPS`
("module:attribute" of a generator function yielding between steps), by default the
product's (`assistant.warmup.steps:warm_steps`).
"""

from __future__ import annotations

import contextlib
import importlib
import os
import sys

DEFAULT_STEPS = "assistant.warmup.steps:warm_steps"


def main() -> int:
    with contextlib.suppress(OSError, AttributeError):
        os.nice(10)
    # lazy points numba at the kernels' cache folder before it imports numba
    from assistant.kernels.lazy import REGISTRY, write_marker

    module, _, attr = os.environ.get("CELLTEACH_WARM_STEPS", DEFAULT_STEPS).partition(":")
    steps = getattr(importlib.import_module(module), attr)
    reported: set[str] = set()

    def say(line: str) -> None:
        # OSError: the command that started us has exited; keep filling the cache
        with contextlib.suppress(OSError):
            print(line, flush=True)

    def report() -> None:
        for name, disp in list(REGISTRY.items()):
            if name not in reported and disp.overloads:
                reported.add(name)
                say(f"ready {name}")

    for _ in steps():
        report()
    report()
    write_marker(len(reported))
    say("done")
    return 0


if __name__ == "__main__":
    sys.exit(main())
