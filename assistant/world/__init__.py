"""The world model: what the assistant knows about the cell around the robot (SPEC §3-4).

Owns the linear octree (`octree`), the fusion of occupancy sources (`fusion`), the reachability
look-up table of joint positions per leaf (`reachability`), the rasterisation of CAD into cells
and the validation of joint positions against CAD (`rasterise`, `chain_levels`), operator
collision indications (`indications`) and the `WorldModel` that ties them together (`model`).

Must not import the planners (`assistant.roadmap`), the UI (`web`, `viser`) or `workflow`:
planners read the world, never the other way round. Units: metres and radians; cells are
addressed by Morton codes in the octree and by flat dense indices in the grid views.
"""
