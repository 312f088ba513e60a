"""The public surface of ``import ident``: every exported name resolves, and ``ident.identify``
is the sub-package whatever was imported first (it used to be a function on first access and
the sub-package afterwards, so the docstring's example failed with "'module' object is not
callable")."""

import importlib
import re
import subprocess
import sys

import numpy as np
from conftest import REPO_ROOT


def test_every_exported_name_resolves():
    import ident

    for name in ident.__all__:
        assert getattr(ident, name) is not None, name


def test_documented_example_after_the_subpackage_was_imported():
    # the sub-package first (as any `from ident.identify... import` does), then the example
    code = f"""
import ident.identify.pipeline.real
import ident
cfg = ident.load_identify_config({str(REPO_ROOT / "configs" / "examples" / "wide-csv.yaml")!r})
identified = ident.identify_config(cfg)
assert identified.estimate.x.shape == (len(identified.parameters.base_names),)
assert type(ident.identify).__name__ == "module"
print("ok")
"""
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == "ok"


def test_identify_config_is_the_core_on_the_log_it_reads():
    import ident
    from ident.measure.logs import read_log

    cfg = ident.load_identify_config(REPO_ROOT / "configs" / "examples" / "wide-csv.yaml")
    a = ident.identify_config(cfg)
    log = read_log(cfg.log, cfg.transmission, list(a.joint_names))
    b = ident.identify_measurements(cfg, log)
    np.testing.assert_array_equal(a.estimate.x, b.estimate.x)


def test_docstring_example_names_exist():
    ident = importlib.import_module("ident")
    used = set(re.findall(r"ident\.([a-z_A-Z]+)\(", ident.__doc__))
    assert used
    assert used <= set(ident.__all__), used - set(ident.__all__)
