"""``ident identify --scheduler``: the chunks of a long log on a dask cluster give the same
estimate as in this process; a bad address is one error line and writes nothing."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import yaml
from typer.testing import CliRunner

from ident.cli import app

ROOT = Path(__file__).resolve().parents[1]


def _chunked_config(tmp_path: Path) -> Path:
    """configs/examples/wide-csv.yaml forced through the chunked path (several chunks)."""
    cfg = yaml.safe_load((ROOT / "configs" / "examples" / "wide-csv.yaml").read_text())
    cfg["robot"]["urdf"] = str(ROOT / "data" / "examples" / "arm3.urdf")
    for signal in ("time", "position", "torque"):
        cfg["log"][signal]["path"] = str(ROOT / "data" / "examples" / "wide.csv")
    cfg["preprocess"].update(chunked="always", chunk_samples=300)
    path = tmp_path / "chunked.yaml"
    path.write_text(yaml.safe_dump(cfg))
    return path


def _estimate(run_out: Path) -> dict[str, float]:
    (run_dir,) = run_out.iterdir()
    data = json.loads((run_dir / "result.json").read_text())
    return {p["name"]: p["value"] for p in data["base_parameters"]}


def _invoke(*args: str):
    return CliRunner().invoke(app, ["identify", *args, "--no-replay"])


def test_scheduler_gives_the_local_estimate(tmp_path):
    distributed = pytest.importorskip("distributed")
    cfg = str(_chunked_config(tmp_path))
    local = _invoke(cfg, "--out", str(tmp_path / "local"))
    assert local.exit_code == 0, local.output
    with distributed.LocalCluster(n_workers=1, processes=False, dashboard_address=None) as lc:
        remote = _invoke(
            cfg, "--out", str(tmp_path / "remote"), "--scheduler", lc.scheduler_address
        )
    assert remote.exit_code == 0, remote.output
    a, b = _estimate(tmp_path / "local"), _estimate(tmp_path / "remote")
    assert a.keys() == b.keys()
    np.testing.assert_allclose([b[k] for k in a], list(a.values()), rtol=1e-12, atol=1e-12)
    (run_dir,) = (tmp_path / "remote").iterdir()
    info = json.loads((run_dir / "run.json").read_text())
    assert info["scheduler"] == lc.scheduler_address
    # the chunks went through the chunked path, not the in-memory one
    assert "chunked accumulation" in (run_dir / "report.md").read_text()


def test_unreachable_scheduler_is_one_error_line(tmp_path, monkeypatch):
    pytest.importorskip("distributed")
    import ident.identify.estimation.log_chunks as log_chunks

    monkeypatch.setattr(log_chunks, "DASK_CONNECT_TIMEOUT", "1s")
    out = tmp_path / "runs"
    res = _invoke(
        str(_chunked_config(tmp_path)), "--out", str(out), "--scheduler", "tcp://127.0.0.1:9"
    )
    assert res.exit_code == 2
    assert "cannot reach the dask scheduler" in res.output
    assert "Traceback" not in res.output
    assert not out.exists() or not any(out.iterdir())


@pytest.mark.parametrize("address", ["", "   "])
def test_empty_scheduler_is_refused(tmp_path, address):
    out = tmp_path / "runs"
    res = _invoke(str(_chunked_config(tmp_path)), "--out", str(out), "--scheduler", address)
    assert res.exit_code == 2
    assert res.output.count("error:") == 1
    assert "--scheduler" in res.output
    assert not out.exists() or not any(out.iterdir())
