"""The package layering: imports run one way, down the data flow, with no cycle.

The contract is in pyproject.toml ([tool.importlinter]); import-linter checks every import of
every module (module-level and inside functions) against it.
"""

import grimp
from conftest import REPO_ROOT
from importlinter.cli import lint_imports


def test_packages_import_only_the_layers_below_them() -> None:
    assert lint_imports(config_filename=str(REPO_ROOT / "pyproject.toml"), no_cache=True) == 0


def test_no_two_modules_import_each_other() -> None:
    graph = grimp.build_graph("ident")
    cycles = sorted(
        (a, b)
        for a in graph.modules
        for b in graph.find_modules_directly_imported_by(a)
        if a < b and a in graph.find_modules_directly_imported_by(b)
    )
    assert cycles == []
