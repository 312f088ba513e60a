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
