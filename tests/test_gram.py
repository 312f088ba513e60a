"""Gram matrices of selected, weighted regressor rows, against the Pinocchio regressor."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from robots import random_chain

from ident.dynamics.chain import chain_from_model, random_states
from ident.dynamics.gram import regressor_gram, selected_rows
from ident.dynamics.pinocchio_check import pinocchio_regressor
from ident.errors import DataError

DATA = Path(__file__).parent / "data" / "urdf"


def _unaligned_model() -> pin.Model:
    revolute, prismatic = pin.JointModelRevoluteUnaligned, pin.JointModelPrismaticUnaligned
    return random_chain([revolute, revolute, prismatic, revolute], seed=3)


@pytest.fixture(scope="module")
def robot():
    model = _unaligned_model()
    chain = chain_from_model(model)
    q, dq, ddq = random_states(chain, 600, rng=5)  # more than one buffer of samples
    return model, chain, (q, dq, ddq), pinocchio_regressor(model, q, dq, ddq)


def test_gram_of_selected_weighted_rows_equals_the_explicit_product(robot) -> None:
    _, chain, states, reference = robot
    rows, columns = [1, 3], [12, 15, 3, 30, 39, 27]
    weights = np.array([2.0, 0.5, 3.0, 1.5])
    W = (weights[rows, None] * reference[:, rows][:, :, columns]).reshape(-1, len(columns))
    np.testing.assert_allclose(
        selected_rows(chain, *states, rows=rows, columns=columns, row_weights=weights),
        W,
        atol=1e-10,
    )
    G = regressor_gram(chain, *states, rows=rows, columns=columns, row_weights=weights)
    np.testing.assert_allclose(G, W.T @ W, rtol=1e-12, atol=1e-12 * np.abs(W.T @ W).max())


def test_gram_defaults_to_the_full_regressor_and_batches(robot) -> None:
    _, chain, (q, dq, ddq), reference = robot
    full = reference.reshape(-1, 40)
    G = regressor_gram(chain, q, dq, ddq)
    np.testing.assert_allclose(G, full.T @ full, atol=1e-11 * np.abs(full.T @ full).max())
    batch = regressor_gram(
        chain,
        np.stack([q[:7], q[7:14]]),
        np.stack([dq[:7], dq[7:14]]),
        np.stack([ddq[:7], ddq[7:14]]),
        columns=[0, 11, 22],
    )
    for b, part in enumerate((slice(0, 7), slice(7, 14))):
        W = reference[part][:, :, [0, 11, 22]].reshape(-1, 3)
        np.testing.assert_allclose(batch[b], W.T @ W, atol=1e-11 * np.abs(W.T @ W).max())


def test_gram_input_errors(robot) -> None:
    _, chain, (q, dq, ddq), _ = robot
    with pytest.raises(DataError, match="columns must be non-empty indices in"):
        regressor_gram(chain, q, dq, ddq, columns=[40])
    with pytest.raises(DataError, match=r"row_weights must have shape \(4,\)"):
        regressor_gram(chain, q, dq, ddq, row_weights=[1.0, 2.0])
    with pytest.raises(DataError, match="ddq must have shape"):
        regressor_gram(chain, q, dq, ddq[:, :2])
