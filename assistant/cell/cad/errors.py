"""The one error a CAD import raises: it names the file, what is wrong and what to do."""

from __future__ import annotations


class CadImportError(ValueError):
    """A CAD file that cannot be used as it is.

    The message is meant for the operator: it names the file, says what is wrong with it and
    what to do about it (export again, give the units, give an extrusion height...).
    """

    def __init__(self, filename: str, problem: str, advice: str = ""):
        self.filename = filename
        self.problem = problem
        self.advice = advice
        text = f"{filename!r}: {problem}"
        if advice:
            text += f" — {advice}"
        super().__init__(text)
