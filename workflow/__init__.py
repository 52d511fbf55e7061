"""The operator workflow as a finite-state machine. Knows nothing of viser or the domain objects."""
