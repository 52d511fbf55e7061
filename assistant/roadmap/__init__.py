"""Roadmap planning in the world model (SPEC §5-6): cell-extension Voronoi roads, lazy A* over
the joint positions stored in road cells, and the `RoadmapPlanner` facade.

Reads `assistant.world` (octree grid views, valid joint positions) and checks motions only
through the `ValidityChecker` protocol (`assistant.collision.validity`). Must not import
the UI (`web`, `viser`) or `workflow`. The elastic net, primitive fitting and the re-planning
loop consume `RoadmapPlan.joint_path` and live elsewhere.
"""
