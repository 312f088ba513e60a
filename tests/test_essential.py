import numpy as np

from ident.identify.estimation.essential import essential_parameters


def test_drops_weak_zero_parameters_and_keeps_the_fit():
    rng = np.random.default_rng(0)
    m = 3000
    strong = rng.normal(size=(m, 4))
    weak = 1e-3 * rng.normal(size=(m, 2))  # barely excited, true value 0
    W = np.hstack([strong, weak])
    x = np.array([1.0, -2.0, 3.0, 0.5, 0.0, 0.0])
    tau = W @ x + 0.05 * rng.normal(size=m)
    names = ["a", "b", "c", "d", "w1", "w2"]
    result = essential_parameters(W, tau, names, max_relative_std_pct=10.0)
    assert result.estimate.names == ("a", "b", "c", "d")
    assert sorted(d["name"] for d in result.dropped) == ["w1", "w2"]
    assert all(d["relative_std_pct"] > 10.0 for d in result.dropped)
    np.testing.assert_allclose(result.estimate.x, x[:4], atol=5e-3)
    assert np.all(result.estimate.relative_std <= 10.0)
    assert result.kept == (0, 1, 2, 3)


def test_stops_when_the_fit_would_degrade():
    rng = np.random.default_rng(1)
    m = 400
    W = rng.normal(size=(m, 3))
    x = np.array([1.0, 0.05, 2.0])  # b is real but noisy: relative std > 10 %
    tau = W @ x + 1.0 * rng.normal(size=m)
    result = essential_parameters(
        W, tau, ["a", "b", "c"], max_relative_std_pct=1.0, max_residual_increase=1e-6
    )
    assert len(result.estimate.names) == 3
    assert "would raise the relative residual" in result.stop_reason
    assert result.dropped == ()
