"""From a searched path to a verified robot trajectory, and application paths into motions.

Owns: the elastic net (particles, forces, IK back-projection), line/arc primitive fitting,
trajectory assembly with dense joint paths and exact verification, application paths
(lines, arcs, Bezier chains) into motions, and mission ordering.

Sees the world only through small interfaces: an `allowed(points)` callback (the octree),
a `ValidityChecker` and a `PathVerifier` (FCL's `CollisionChecker` serves both). Must not
import the world model or roadmap packages, nor any UI (viser).
"""
