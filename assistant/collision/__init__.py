"""Collision: the exact checker (FCL) behind a compiled sphere broad phase and pruning,
motion and path checks, clearance scans, the validity interface the planners see.

May import: robots, transforms, kernels.
"""
