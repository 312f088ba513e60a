"""Shared pytest setup: every test runs from the repository root.

Tests name project files by their repository paths (``configs/paper6r.yaml``,
``robot/urdf/paper6r.urdf``), as a user would from a checkout; this makes ``pytest`` give the
same result whatever folder it is started from.
"""

import os
from pathlib import Path

import pytest

REPO_ROOT = Path(__file__).resolve().parents[1]

# Some test modules load the paper robot at import time, during collection.
os.chdir(REPO_ROOT)


@pytest.fixture(autouse=True)
def _run_from_repository_root(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(REPO_ROOT)


@pytest.fixture(scope="session")
def shipped_run(tmp_path_factory: pytest.TempPathFactory):
    """``shipped_run(name)``: the folder of ``ident run configs/<name>.yaml --no-replay`` (exit
    0 asserted), run once per session and shared by the tests that inspect it."""
    from typer.testing import CliRunner

    from ident.cli import app

    folders: dict[str, Path] = {}

    def run(name: str) -> Path:
        if name not in folders:
            out = tmp_path_factory.mktemp(f"shipped-{name}")
            config = REPO_ROOT / "configs" / f"{name}.yaml"
            result = CliRunner().invoke(app, ["run", str(config), "--out", str(out), "--no-replay"])
            assert result.exit_code == 0, result.output
            (folders[name],) = [p for p in out.iterdir() if p.is_dir()]
        return folders[name]

    return run
