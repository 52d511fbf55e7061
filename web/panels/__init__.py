"""One panel per workflow step (SPEC §1: the page shows only the current step's panel)."""
