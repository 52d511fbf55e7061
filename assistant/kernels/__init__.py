"""Compiled-kernel plumbing: the `kernel` decorator, numba's cache folder, shared helpers.

Owns how numba kernels are compiled, cached and switched on, so that no operator action
waits on a compile. Imports only numba and the standard library; every kernel module of the
domain imports `kernel` from here. The warm-up and the background compile, which drive the
domain's API, live above every room in `assistant.warmup`.
"""
