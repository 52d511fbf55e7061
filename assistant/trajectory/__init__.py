"""From a searched path to a verified robot trajectory, and application paths into motions.

Owns: the elastic net (particles, forces, IK back-projection), line/arc primitive fitting,
trajectory assembly with dense joint paths and exact verification, application paths
(lines, arcs, Bezier chains: `bezier`, `bezier_drawings`) into motions, and mission
ordering.

Sees the world only through small interfaces: an `allowed(points)` callback (the octree),
a `ValidityChecker` and a `PathVerifier` (FCL's `CollisionChecker` serves both); of the
world model only the compiled leaf lookup (`world.leaf_lookup`) inside the net's kernel.
Must not import the roadmap, planning or any UI (viser).
"""
