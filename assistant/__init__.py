"""cellteach domain core: robots, cell and CAD, collision, world model, planning, export, links.

Owns every rule of the domain. Must not import `web` or `viser`: the web page renders what the
`Session` facade exposes and calls its methods, nothing more. Units inside: metres and radians.
"""

__version__ = "0.1.0"

# Before any kernel module is imported: numba reads its cache folder when a kernel is defined.
from assistant.kernels.cache import configure as _configure_kernel_cache  # noqa: E402

_configure_kernel_cache()
