"""The README shows the workflow diagram generated from the code, not a stale copy."""

from pathlib import Path

from workflow.mermaid import diagram


def test_readme_holds_the_current_workflow_diagram():
    readme = (Path(__file__).resolve().parents[2] / "README.md").read_text(encoding="utf-8")
    assert f"```mermaid\n{diagram()}\n```" in readme, \
        "regenerate the README diagram with: python -m workflow.mermaid"
