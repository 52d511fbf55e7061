"""The 3-D scene, one module per layer: robot, objects, locations, application paths, world
model (occupancy + roads), the planned path and the live pointer. Each layer redraws itself
from session queries when an event says its part changed."""
