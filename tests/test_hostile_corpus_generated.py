"""``tests/data/hostile/generate.py`` reproduces the committed corpus byte for byte.

A case added by hand to ``manifest.yaml`` or a file edited in place would be lost at the next
regeneration; a generator writing time stamps (gzip, zip) or dropping a manifest comment would
change bytes nobody meant to change. The generator runs on a copy of the corpus (its real
``ident run`` folder is kept, as a plain regeneration does), and every file of the copy must
equal the committed one.
"""

from __future__ import annotations

import filecmp
import importlib.util
import os
import shutil
from pathlib import Path

CORPUS = Path(__file__).resolve().parent / "data" / "hostile"


def _files(root: Path) -> set[str]:
    return {
        str(Path(d, f).relative_to(root))
        for d, _, names in os.walk(root)
        for f in names
        if "__pycache__" not in d
    }


def test_generate_reproduces_the_committed_corpus(tmp_path, monkeypatch, capsys):
    copy = tmp_path / "hostile"
    shutil.copytree(CORPUS, copy, ignore=shutil.ignore_patterns("__pycache__"))
    monkeypatch.setenv("IDENT_HOSTILE_DIR", str(copy))  # the scripts write the copy
    spec = importlib.util.spec_from_file_location("hostile_generate", CORPUS / "generate.py")
    assert spec is not None
    assert spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    assert module.HERE == copy
    module.main()
    capsys.readouterr()
    committed, generated = _files(CORPUS), _files(copy)
    assert generated == committed, (generated - committed, committed - generated)
    changed = [f for f in sorted(committed) if not filecmp.cmp(CORPUS / f, copy / f, shallow=False)]
    assert changed == [], changed
