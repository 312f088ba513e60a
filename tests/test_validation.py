import numpy as np
import pytest

from ident.errors import ConfigError
from ident.identify.estimation.reference import (
    expression_to_vector,
    parse_expression,
    read_reference,
)
from ident.identify.estimation.validation import held_out_warnings, prediction_metrics, time_split


def test_prediction_metrics_closed_form():
    tau = np.array([[1.0, 2.0], [3.0, -2.0], [-1.0, 0.0]])
    pred = tau + np.array([[0.1, 0.0], [-0.1, 0.0], [0.1, 1.0]])
    m = prediction_metrics(tau, pred)
    np.testing.assert_allclose(m.rmse, [0.1, np.sqrt(1 / 3)])
    np.testing.assert_allclose(m.relative_residual, [np.sqrt(0.03 / 11), 1 / np.sqrt(8)])
    assert m.total_relative_residual == pytest.approx(np.sqrt(1.03 / 19))
    assert m.r2[0] == pytest.approx(1 - 0.03 / np.sum((tau[:, 0] - 1) ** 2))


def test_prediction_metrics_mask_ignores_entries():
    rng = np.random.default_rng(0)
    tau = rng.normal(size=(50, 2))
    pred = tau + 0.1
    pred[:5, 1] += 100.0  # masked out below
    mask = np.ones_like(tau, dtype=bool)
    mask[:5, 1] = False
    m = prediction_metrics(tau, pred, mask)
    np.testing.assert_allclose(m.rmse, [0.1, 0.1])
    full = prediction_metrics(tau[5:], pred[5:])
    assert m.relative_residual[1] == pytest.approx(full.relative_residual[1])


def test_time_split():
    ident, val = time_split(10, 0.7)
    assert (ident, val) == (slice(0, 7), slice(7, 10))
    assert time_split(10, 1.0)[1] == slice(10, 10)
    with pytest.raises(ConfigError, match="identify_fraction"):
        time_split(10, 0.01)


def test_reference_expressions(tmp_path):
    terms = parse_expression("Ixx2 - 1.0*Iyy2 - 0.050625*m3 + 2.5e-3*mx4")
    assert terms == {"Ixx2": 1.0, "Iyy2": -1.0, "m3": -0.050625, "mcx4": 0.0025}
    vector = expression_to_vector(terms, ("Ixx2", "Iyy2", "m3", "mcx4", "fv1"))
    np.testing.assert_allclose(vector, [1.0, -1.0, -0.050625, 0.0025, 0.0])
    assert expression_to_vector({"nope1": 1.0}, ("Ixx2",)) is None
    path = tmp_path / "bp.csv"
    path.write_text("Izz1 + 1.0*Ia1,1.2,0.9,1.3,1.1\nfv1,8.1,0.5,8.0,0.6\n")
    (first, second) = read_reference(path)
    assert first.lead == "Izz1"
    assert first.value("wls") == (1.3, 1.1)
    assert second.value("ols") == (8.1, 0.5)


def test_held_out_warnings_against_nominal_and_bound():
    assert held_out_warnings(0.2, 1.0) == []
    assert held_out_warnings(0.2, None, max_relative_residual=0.25) == []
    (w,) = held_out_warnings(1.288, 1.064, n_rows=218, n_params=60)
    assert w.startswith("held-out relative residual of the identified parameters 1.288 is not")
    assert "nominal parameters' (1.064)" in w
    assert "(218 identification rows for 60 parameters)" in w
    # equal is not better
    assert len(held_out_warnings(0.5, 0.5)) == 1
    (w,) = held_out_warnings(0.3, 1.0, max_relative_residual=0.25)
    assert "0.3 exceeds validation.max_relative_residual = 0.25" in w
    assert len(held_out_warnings(1.3, 1.0, max_relative_residual=0.25)) == 2
    # a NaN prediction error is never accepted by the bound
    assert len(held_out_warnings(float("nan"), None, max_relative_residual=1.0)) == 1
    (w,) = held_out_warnings(2.0, 1.0, in_sample=True)
    assert w.startswith("on the identification rows (no held-out part) relative residual")
