"""cellteach domain core: robots, cell and CAD, collision, world model, planning, export, links.

Owns every rule of the domain. Must not import `web` or `viser`: the web page renders what the
`Session` facade exposes and calls its methods, nothing more. Units inside: metres and radians.

Importing the package does no work: `assistant.Session` is looked up on first use (PEP 562),
and numba is pointed at its cache folder by the kernel plumbing when numba is first imported
(`assistant.kernels.lazy`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

__version__ = "0.1.0"
__all__ = ["Session", "__version__"]

if TYPE_CHECKING:
    from assistant.session.session import Session


def __getattr__(name: str) -> Any:
    if name == "Session":
        from assistant.session.session import Session

        return Session
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
