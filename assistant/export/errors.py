"""The one error the exporter raises for input it will not turn into a program.

A robot program that is silently wrong is worse than none: every refusal names the mission
step (the `Motion.label`) and what is wrong, so the operator can fix the mission.
"""

from __future__ import annotations


class ExportError(ValueError):
    """A program that a controller would reject or that would not do what was planned."""

    def __init__(self, message: str, *, step: str = "", dialect: str = ""):
        where = f"step {step!r}: " if step else ""
        super().__init__(f"{where}{message}")
        self.step = step
        self.dialect = dialect
        self.detail = message
