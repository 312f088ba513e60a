import os
import stat

import pytest

from ident.fileio import atomic_write_bytes, atomic_write_text


def test_atomic_write_creates_parents_and_content(tmp_path):
    path = atomic_write_text(tmp_path / "a" / "b.txt", "héllo")
    assert path.read_text(encoding="utf-8") == "héllo"
    assert not [p for p in path.parent.iterdir() if p.name.endswith(".tmp")]


def test_permissions_follow_umask_like_open(tmp_path):
    old = os.umask(0o022)
    try:
        path = atomic_write_bytes(tmp_path / "x.bin", b"1")
    finally:
        os.umask(old)
    assert stat.S_IMODE(path.stat().st_mode) == 0o644


def test_failed_write_leaves_old_file_and_no_temp(tmp_path):
    path = atomic_write_text(tmp_path / "keep.txt", "old")

    with pytest.raises(TypeError):
        atomic_write_bytes(path, "not bytes")  # type: ignore[arg-type]
    assert path.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["keep.txt"]
