"""docs/workflow.md shows the workflow diagram generated from the code, not a stale copy."""

from pathlib import Path

from workflow.mermaid import diagram


def test_the_docs_hold_the_current_workflow_diagram():
    doc = (Path(__file__).resolve().parents[2] / "docs" / "workflow.md").read_text(
        encoding="utf-8")
    assert f"```mermaid\n{diagram()}\n```" in doc, \
        "regenerate the diagram in docs/workflow.md with: python -m workflow.mermaid"
