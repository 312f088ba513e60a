"""``ident identify`` estimates the memory and time of a log before identifying it: printed
for a long one, refused above the ceilings (IDENT_MAX_MEMORY_GB / IDENT_MAX_HOURS) with
nothing written."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from ident.cli import app
from ident.identify.config import load_identify_config
from ident.identify.pipeline import real
from ident.measure.logs import read_log

ROOT = Path(__file__).resolve().parents[1]
CONFIG = ROOT / "configs" / "examples" / "wide-csv.yaml"


def _log(cfg, n_samples=None):
    log = read_log(cfg.log, cfg.transmission, ["j1", "j2", "j3"], source=str(CONFIG))
    if n_samples is None:
        return log
    # the estimate reads only the shape and the segments of the log
    q = np.broadcast_to(np.float64(0.0), (n_samples, 3))
    return dataclasses.replace(log, q=q, segments=((0, n_samples),))


def _invoke(out: Path):
    return CliRunner().invoke(app, ["identify", str(CONFIG), "--out", str(out), "--no-replay"])


def test_in_memory_estimate_is_the_whole_log_as_one_chunk():
    import ident.identify.estimation.accumulate as accumulate
    import ident.identify.estimation.log_chunks as log_chunks

    cfg = load_identify_config(CONFIG)
    nv, n = 3, 10**5
    est = real.estimate_identify(cfg, _log(cfg, n))
    # closed form: the log (t, q, tau), the whole log as one chunk of rigid (10 nv) + extra
    # (4 nv) columns (decimation auto: counted as none), the uncertainty's blocks
    assert cfg.preprocess.decimation == "auto"
    step = 1
    per_sample = 8.0 * 4 * nv + 2 * 8.0 * nv * (14 * nv + 2) / step
    chunk = n * per_sample + 4 * accumulate.ROW_BLOCK * 8.0 * nv * (14 * nv + 2)
    assert chunk == pytest.approx(log_chunks.chunk_bytes(n, nv, 14 * nv, step))
    blocks = 8.0 * log_chunks.MAX_BLOCKS * (14 * nv) ** 2
    assert est.memory_bytes == pytest.approx(400e6 + 8.0 * n * (2 * nv + 1) + chunk + blocks)
    assert est.seconds == pytest.approx(n * nv**2 * 2.5e-7)
    assert "in memory" in est.what
    # above preprocess.max_regressor_mb (1 GB) the automatic path is by chunks
    assert "by chunks" in real.estimate_identify(cfg, _log(cfg, 10**6)).what


def test_chunked_estimate_grows_only_with_the_log_arrays():
    cfg = load_identify_config(CONFIG)
    pp = cfg.preprocess.model_copy(update={"chunked": "always", "chunk_samples": 1000})
    cfg = cfg.model_copy(update={"preprocess": pp})
    small, big = (real.estimate_identify(cfg, _log(cfg, n)) for n in (10**6, 2 * 10**6))
    assert "by chunks" in big.what
    assert big.memory_bytes - small.memory_bytes == pytest.approx(8.0 * 10**6 * (2 * 3 + 1))
    assert big.seconds == pytest.approx(2 * small.seconds)


def test_estimate_of_the_long_log_benchmark():
    # benchmarks/bench_identify_long.py, measured: 3.6 million samples x 7 joints by chunks,
    # 26 s wall (41 s of CPU) on a quiet 2-core machine, peak 900 MiB; the estimate is of that
    # order and errs long (one core's time) and high
    import ident.identify.estimation.log_chunks as log_chunks

    cfg = load_identify_config(CONFIG)
    log = _log(cfg, 10)
    q = np.broadcast_to(np.float64(0.0), (3_600_000, 7))
    est = real.estimate_identify(cfg, dataclasses.replace(log, q=q, segments=((0, q.shape[0]),)))
    assert log_chunks.use_chunks(dataclasses.replace(log, q=q), cfg.preprocess, 98)
    assert "by chunks" in est.what
    assert 41 < est.seconds < 3 * 41
    assert 900 * 2**20 < est.memory_bytes < 1.5 * 900 * 2**20


def test_long_log_estimate_is_printed(tmp_path, monkeypatch):
    monkeypatch.setattr(real, "_SECONDS_PER_SAMPLE_JOINT2", 1.0)  # the log looks hours long
    monkeypatch.setenv("IDENT_MAX_HOURS", "1000")
    res = _invoke(tmp_path / "runs")
    assert res.exit_code == 0, res.output
    assert "estimate: identify: 1600 samples x 3 joints, in memory: about" in res.output


def test_short_log_estimate_is_not_printed(tmp_path):
    res = _invoke(tmp_path / "runs")
    assert res.exit_code == 0, res.output
    assert "estimate:" not in res.output


@pytest.mark.parametrize(
    ("variable", "ceiling"),
    [("IDENT_MAX_MEMORY_GB", "memory ceiling"), ("IDENT_MAX_HOURS", "time ceiling")],
)
def test_above_a_ceiling_is_refused_before_any_run_folder(tmp_path, monkeypatch, variable, ceiling):
    monkeypatch.setenv(variable, "1e-9")
    out = tmp_path / "runs"
    res = _invoke(out)
    assert res.exit_code == 2
    assert res.output.count("error:") == 1
    assert ceiling in res.output
    assert variable in res.output
    assert "Traceback" not in res.output
    assert not out.exists() or not any(out.iterdir())
