"""benchmarks/bench_excitation.py: it optimizes the pipeline's own objective, keeps the budget,
and its statistics name the right winner."""

import importlib.util
import json
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def bench():
    spec = importlib.util.spec_from_file_location(
        "bench_excitation", ROOT / "benchmarks" / "bench_excitation.py"
    )
    module = importlib.util.module_from_spec(spec)
    sys.modules["bench_excitation"] = module
    spec.loader.exec_module(module)
    return module


def test_the_benchmark_scores_what_ident_run_optimized(bench, shipped_run):
    # the fitness `ident run configs/wrist-fourier.yaml` recorded for its elites (objective
    # with the safety terms) is what the benchmark's problem gives at the same designs; an
    # objective without the safety section, other base columns or another criterion differ
    run = shipped_run("wrist-fourier")
    elites = json.loads((run / "result.json").read_text())["elites"]
    _, problem = bench.load_problem("wrist-fourier")
    x = np.array([e["x"] for e in elites])
    np.testing.assert_allclose(problem.objective(x), [e["fitness"] for e in elites], rtol=1e-9)
    assert problem.objective.safety is not None


def test_statistics_name_the_winner(bench):
    rng = np.random.default_rng(0)
    base = rng.normal(10.0, 1.0, 10)
    values = {"emupso": list(base), "cma": list(base - 1.0 - rng.uniform(0, 0.1, 10))}
    assert bench.wilcoxon_vs(values, "cma", "emupso").endswith("<")
    assert float(bench.wilcoxon_vs(values, "cma", "emupso").split()[0]) < 0.01
    assert bench.wilcoxon_vs(values, "emupso", "emupso") == "-"
    ranks = bench.mean_ranks(values)
    assert ranks == {"emupso": 2.0, "cma": 1.0}


def test_every_method_within_the_budget_and_identified(bench, monkeypatch, capsys):
    calls = []
    original = bench._run_method

    def counting(problem, method, x0, budget, rng, stall):
        res = original(problem, method, x0, budget, rng, stall)
        calls.append((method, budget, res.nfev))
        return res

    monkeypatch.setattr(bench, "_run_method", counting)
    bench.main(
        ["--problems", "wrist", "--seeds", "1", "--budget-factor", "0.05",
         "--methods", "emupso", "cma", "emupso-5x"]
    )  # fmt: skip
    out = capsys.readouterr().out
    budget = int(bench.PIPELINE_BUDGET * 0.05)
    assert all(nfev <= b for _, b, nfev in calls)
    assert sum(b for m, b, _ in calls if m == "emupso") == 2 * budget  # one run + 5 short ones
    rows = [line.split()[0] for line in out.splitlines() if line.split()[:1] and
            line.split()[0] in ("emupso", "cma", "emupso-5x")]  # fmt: skip
    assert rows == ["emupso", "cma", "emupso-5x"]
    assert "elite search found every elite on 1 of 1 seeds" in out


def test_the_config_split_is_the_pipelines_budget(bench):
    """--split config/both: each config's runs x (maxiter + 1) x particles, as `ident run`
    spends it (its setup's estimate counts the same evaluations)."""
    from ident.run.config import load_run_config

    wrist = load_run_config(ROOT / "configs" / "wrist-fourier.yaml")
    ur5 = load_run_config(ROOT / "configs" / "ur5.yaml")
    assert bench.entries(("pso", "cma"), "both", 3100, wrist) == [
        ("pso:5x620", "pso", 5, 620),
        ("pso:1x3100", "pso", 1, 3100),
        ("cma:5x620", "cma", 5, 620),
        ("cma:1x3100", "cma", 1, 3100),
    ]
    assert bench.entries(("pso",), "both", 3100, ur5) == [("pso:1x3020", "pso", 1, 3020)]
    assert bench.entries(("emupso-5x", "pso"), "one", 3100, wrist) == [
        ("emupso-5x", "emupso", 5, 620),
        ("pso", "pso", 1, 3100),
    ]
