"""The cell: the robot's place, CAD objects (import in `cad/`), frames, placement fits,
saving and loading a cell folder, and the sample cells.

May import: robots, collision (shapes), transforms.
"""
