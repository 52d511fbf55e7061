"""Compiled-kernel plumbing: the `kernel` decorator, numba's cache folder, the warm-up.

Owns how numba kernels are compiled, cached and switched on, so that no operator action
waits on a compile. Imports only numba and the standard library at module level (the
warm-up imports the domain modules it exercises when it runs); every kernel module of the
domain imports `kernel` from here.
"""
