"""The warm-up and the background compile: drive the real API once so that numba compiles
(or loads from its cache) every kernel before an operator action would wait on it.

Sits beside the CLI, above every room it exercises (collision, robots, roadmap, trajectory,
world); the plumbing it drives (`assistant.kernels`: the `kernel` decorator, the cache
folder, the switch from fallbacks to machine code) stays at the bottom.
"""
