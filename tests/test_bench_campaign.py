"""The benchmark campaign: determinism, parallel paths, statistics, CLI end to end."""

from __future__ import annotations

import builtins
import csv
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from ident.bench.campaign import (
    CampaignConfig,
    CampaignResult,
    RunRecord,
    load_campaign_config,
    run_campaign,
    wilcoxon_p,
    wilcoxon_table,
    win_tie_loss,
)
from ident.cli import app
from ident.errors import ConfigError, IdentError

ROOT = Path(__file__).resolve().parents[1]
TINY = dict(name="tiny", seed=3, runs=3, popsize=8, max_nfev=120, methods=["emupso", "de"],
            functions=["camel6", "sphere"], curve_points=5)  # fmt: skip


def _errors(res: CampaignResult) -> dict:
    return {(r.function, r.method, r.run): (r.error, tuple(r.curve_error)) for r in res.records}


def test_results_do_not_depend_on_workers():
    cfg = CampaignConfig(**TINY)
    a = run_campaign(cfg, workers=1)
    b = run_campaign(cfg, workers=2)
    assert _errors(a) == _errors(b)
    assert len(a.records) == 2 * 2 * 3
    assert [r.run for r in a.records[:3]] == [0, 1, 2]
    # runs differ from each other (independent seeds)
    assert len(set(a.errors("sphere", "de"))) == 3


def test_seeds_do_not_depend_on_config_composition():
    a = run_campaign(CampaignConfig(**TINY))
    b = run_campaign(CampaignConfig(**{**TINY, "methods": ["de"], "functions": ["sphere"]}))
    np.testing.assert_array_equal(a.errors("sphere", "de"), b.errors("sphere", "de"))


def test_dask_local_cluster_gives_identical_results():
    distributed = pytest.importorskip("distributed")
    cfg = CampaignConfig(**TINY)
    with distributed.LocalCluster(n_workers=1, processes=False, dashboard_address=None) as lc:
        seen = []
        res = run_campaign(cfg, scheduler=lc.scheduler_address,
                           progress=lambda d, t: seen.append((d, t)))  # fmt: skip
    assert _errors(res) == _errors(run_campaign(cfg))
    assert seen[-1] == (12, 12)
    assert res.scheduler == lc.scheduler_address


def test_missing_dask_is_a_clear_error(monkeypatch):
    real_import = builtins.__import__

    def no_dask(name, *a, **k):
        if name.startswith("distributed"):
            raise ImportError("no distributed")
        return real_import(name, *a, **k)

    monkeypatch.setattr(builtins, "__import__", no_dask)
    with pytest.raises(IdentError, match=r"pip install 'ident\[dask\]'"):
        run_campaign(CampaignConfig(**TINY), scheduler="tcp://127.0.0.1:1")


def test_wilcoxon_matches_matlab_signrank_values_of_the_spec():
    rng = np.random.default_rng(0)
    a = rng.random(30)
    assert wilcoxon_p(a, a + 1 + rng.random(30)) == pytest.approx(1.73e-6, rel=3e-3)
    d = 1.0 + np.arange(30)
    d[0] = -d[0]  # one reversed smallest rank
    assert wilcoxon_p(a, a + d) == pytest.approx(1.92e-6, rel=3e-3)
    b = a.copy()
    b[:3] += 1 + np.arange(3)  # three non-zero pairs: exact test
    assert wilcoxon_p(a, b) == pytest.approx(0.25)
    b = a.copy()
    b[:8] += 1 + np.arange(8)
    assert wilcoxon_p(a, b) == pytest.approx(0.0078125)
    assert wilcoxon_p(a, a) == 1.0


def _fake(errors: dict[str, dict[str, list[float]]]) -> CampaignResult:
    methods = list(next(iter(errors.values())))
    cfg = CampaignConfig(name="fake", runs=len(next(iter(next(iter(errors.values())).values()))),
                         methods=methods, functions=list(errors))  # fmt: skip
    recs = [
        RunRecord(f, m, i, e, e, 10, 1, 0.0, 0, np.array([10]), np.array([e]))
        for f, per in errors.items()
        for m, es in per.items()
        for i, e in enumerate(es)
    ]
    return CampaignResult(config=cfg, records=tuple(recs), wall_seconds=0.0, workers=1)


def test_tables_7_8_9_definitions():
    n = 20
    res = _fake({
        # sphere (unimodal): pso best alone; de always worse
        "sphere": {"pso": [0.0] * n, "de": list(np.linspace(1, 2, n)), "woa": [1.0] * n},
        # rastrigin (multimodal): all equal -> ties everywhere, p = 1
        "rastrigin": {"pso": [3.0] * n, "de": [3.0] * n, "woa": [3.0] * n},
        # camel6 (fixed): woa best by mean but not significantly better than de (2 pairs)
        "camel6": {"pso": list(5 + np.arange(n)), "de": [0.0] * (n - 2) + [0.1, 0.2],
                   "woa": [0.0] * n},
    })  # fmt: skip
    wt = wilcoxon_table(res)
    assert wt["sphere"][0] == "pso"
    assert wt["sphere"][1]["pso"] is None
    assert wt["sphere"][1]["de"] < 1e-3
    assert wt["rastrigin"][1]["de"] == 1.0
    assert wt["camel6"][0] == "woa"
    assert wt["camel6"][1]["de"] == pytest.approx(0.5)  # exact test, 2 non-zero pairs
    t7 = win_tie_loss(res, "min")
    assert t7["unimodal"] == {"pso": (1, 0, 0), "de": (0, 0, 1), "woa": (0, 0, 1)}
    assert t7["multimodal"] == {"pso": (0, 1, 0), "de": (0, 1, 0), "woa": (0, 1, 0)}
    assert t7["fixed"] == {"pso": (0, 0, 1), "de": (0, 1, 0), "woa": (0, 1, 0)}
    assert t7["total"]["pso"] == (1, 1, 1)
    t9 = win_tie_loss(res, "wilcoxon")
    assert t9["unimodal"] == {"pso": (1, 0, 0), "de": (0, 0, 1), "woa": (0, 0, 1)}
    assert t9["multimodal"]["de"] == (0, 1, 0)
    assert t9["fixed"] == {"pso": (0, 0, 1), "de": (0, 1, 0), "woa": (0, 1, 0)}


def test_config_errors_name_the_key(tmp_path):
    with pytest.raises(ConfigError, match="did you mean 'emupso'"):
        CampaignConfig_from(tmp_path, "methods: [emupos]\n")
    with pytest.raises(ConfigError, match="did you mean 'rastrigin'"):
        CampaignConfig_from(tmp_path, "functions: [rastrigen]\n")
    with pytest.raises(ConfigError, match="did you mean 'stall_threshold'"):
        CampaignConfig_from(
            tmp_path, "methods: [emupso]\nmethod_options: {emupso: {stall_treshold: 3}}\n"
        )
    with pytest.raises(ConfigError, match="smaller than one population"):
        CampaignConfig_from(tmp_path, "popsize: 30\nmax_nfev: 20\n")
    with pytest.raises(ConfigError, match="did you mean 'runs'"):
        CampaignConfig_from(tmp_path, "run: 3\n")


def CampaignConfig_from(tmp_path: Path, text: str) -> CampaignConfig:  # noqa: N802
    p = tmp_path / "c.yaml"
    p.write_text(text)
    return load_campaign_config(p)


def test_shipped_configs_are_valid():
    full = load_campaign_config(ROOT / "configs" / "bench.yaml")
    assert len(full.function_keys()) == 36
    assert full.runs == 30
    assert full.popsize == 30
    assert full.maxiter == 999
    smoke = load_campaign_config(ROOT / "configs" / "bench-smoke.yaml")
    assert smoke.runs < 10


def test_cli_smoke_campaign_end_to_end(tmp_path):
    out = tmp_path / "camp"
    runner = CliRunner()
    cfg = str(ROOT / "configs" / "bench-smoke.yaml")
    res = runner.invoke(app, ["bench", cfg, "--out", str(out), "--no-progress"])
    assert res.exit_code == 0, res.output
    assert "report:" in res.output
    smoke = load_campaign_config(cfg)
    n = len(smoke.methods) * len(smoke.function_keys()) * smoke.runs
    with open(out / "runs.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == n
    assert all(float(r["error"]) >= -1e-12 for r in rows)
    assert all(int(r["nfev"]) <= smoke.max_nfev for r in rows)
    for name in ("curves.csv", "stats.csv", "wilcoxon.csv", "summary.csv", "campaign.json",
                 "report.html", "figures/convergence_fixed.png"):  # fmt: skip
        assert (out / name).is_file(), name
    md = (out / "report.md").read_text()
    for heading in ("Table 4", "Table 6", "Table 7", "Table 8", "Table 9", "disagree"):
        assert heading in md
    assert "f - f_min(paper)" in md
    assert "<img" in (out / "report.html").read_text()
    # the folder can be read back and re-rendered identically
    from ident.bench.report import load_campaign, write_campaign

    write_campaign(load_campaign(out), tmp_path / "again")
    assert (tmp_path / "again" / "stats.csv").read_text() == (out / "stats.csv").read_text()
    assert (tmp_path / "again" / "report.md").read_text() == md
    again = runner.invoke(app, ["bench", cfg, "--out", str(out), "--no-progress"])
    assert again.exit_code == 2
    assert "never overwritten" in again.output


@pytest.mark.slow
def test_dask_tcp_cluster_with_worker_processes():
    distributed = pytest.importorskip("distributed")
    cfg = CampaignConfig(**TINY)
    with distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
    ) as lc:
        assert lc.scheduler_address.startswith("tcp://")
        res = run_campaign(cfg, scheduler=lc.scheduler_address)
    assert _errors(res) == _errors(run_campaign(cfg))


def test_cli_failed_campaign_leaves_no_folder(tmp_path, monkeypatch):
    pytest.importorskip("distributed")
    from ident.identify.estimation import log_chunks  # the one connection to a scheduler

    monkeypatch.setattr(log_chunks, "DASK_CONNECT_TIMEOUT", "1s")
    out = tmp_path / "never"
    cfg = str(ROOT / "configs" / "bench-smoke.yaml")
    res = CliRunner().invoke(
        app, ["bench", cfg, "--out", str(out), "--scheduler", "tcp://127.0.0.1:9", "--no-progress"]
    )
    assert res.exit_code == 2
    assert "cannot reach the dask scheduler" in res.output
    assert not out.exists()


def test_unreachable_scheduler_is_a_clear_error(monkeypatch):
    pytest.importorskip("distributed")
    from ident.identify.estimation import log_chunks  # the one connection to a scheduler

    monkeypatch.setattr(log_chunks, "DASK_CONNECT_TIMEOUT", "1s")
    with pytest.raises(IdentError, match="cannot reach the dask scheduler"):
        run_campaign(CampaignConfig(**TINY), scheduler="tcp://127.0.0.1:9")
