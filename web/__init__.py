"""The viser page: one panel per workflow state, the 3-D scene, downloads. No domain logic."""
