"""What the operator teaches and what the planner hands on: locations, application paths,
the mission (`model`), and the neutral trajectory of moves and tool actions (`motion`).

May import: transforms. Every room above (trajectory, planning, export, session) reads it.
"""
