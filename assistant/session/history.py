"""Undo/redo of the operator's edits as snapshots of the editable document.

The document (object placements, taught locations, mission) is small JSON-able data - CAD
meshes are referenced by content hash, not copied - so a snapshot per accepted edit is cheap
and restoring one can never leave half an edit behind, which a command log could.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any


@dataclass
class History:
    limit: int = 200
    _undo: list[tuple[str, Any]] = field(default_factory=list)
    _redo: list[tuple[str, Any]] = field(default_factory=list)

    def record(self, label: str, before: Any) -> None:
        """Call with the document as it was *before* an accepted edit.

        Documents must be immutable values (see `session.document.Document`): they are kept
        by reference, not copied.
        """
        self._undo.append((label, before))
        if len(self._undo) > self.limit:
            self._undo.pop(0)
        self._redo.clear()

    @property
    def can_undo(self) -> bool:
        return bool(self._undo)

    @property
    def can_redo(self) -> bool:
        return bool(self._redo)

    def undo_label(self) -> str:
        return self._undo[-1][0] if self._undo else ""

    def redo_label(self) -> str:
        return self._redo[-1][0] if self._redo else ""

    def undo(self, current: Any) -> tuple[str, Any]:
        """Return (label, document to restore); `current` goes on the redo stack."""
        if not self._undo:
            raise IndexError("nothing to undo")
        label, doc = self._undo.pop()
        self._redo.append((label, current))
        return label, doc

    def redo(self, current: Any) -> tuple[str, Any]:
        if not self._redo:
            raise IndexError("nothing to redo")
        label, doc = self._redo.pop()
        self._undo.append((label, current))
        return label, doc

    def clear(self) -> None:
        self._undo.clear()
        self._redo.clear()
