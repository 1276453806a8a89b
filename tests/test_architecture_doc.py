"""docs/architecture.md's generated section matches the code (regenerate: python -m tests.architecture_doc)."""
from __future__ import annotations

from tests import architecture_doc as doc


def test_the_generated_package_map_is_current():
    assert doc.updated(doc.DOC.read_text()) == doc.DOC.read_text(), \
        "docs/architecture.md is stale: run python -m tests.architecture_doc"


def test_every_extension_point_names_files_that_exist():
    assert doc.missing_paths() == []


def test_every_package_sits_on_a_floor():
    from tests.test_architecture import G

    placed = {u for floor in doc.FLOORS for u in floor}
    assert set(G) - {"pipeline"} <= placed
