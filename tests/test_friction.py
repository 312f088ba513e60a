import numpy as np
import pytest

from ident.dynamics.friction import (
    ExtraTerms,
    extra_columns,
    extra_names,
    figaroh_coupling_columns,
)
from ident.errors import ConfigError


def test_names_and_order():
    terms = ExtraTerms.from_options(3, rotor_inertia=[1, 3], coulomb=False, coupled_wrist=[2, 3])
    assert extra_names(terms) == (
        "Ia1",
        "fv1",
        "off1",
        "fv2",
        "off2",
        "Ia3",
        "fv3",
        "off3",
        "Iam3",
        "fvm3",
        "fsm3",
    )


def test_columns_enter_their_rows_only():
    rng = np.random.default_rng(0)
    dq, ddq = rng.normal(size=(7, 3)), rng.normal(size=(7, 3))
    terms = ExtraTerms.from_options(3)
    Y = extra_columns(terms, dq, ddq)
    params = rng.normal(size=Y.shape[2])
    p = dict(zip(extra_names(terms), params, strict=True))
    expected = np.column_stack(
        [
            p[f"Ia{j}"] * ddq[:, j - 1]
            + p[f"fv{j}"] * dq[:, j - 1]
            + p[f"fs{j}"] * np.sign(dq[:, j - 1])
            + p[f"off{j}"]
            for j in (1, 2, 3)
        ]
    )
    np.testing.assert_allclose(Y @ params, expected, atol=1e-12)


def test_coupled_wrist_follows_the_transmission():
    # Motor 6 turns with N (q5 + q6); its torque reaches the joints through Rq^T.
    rng = np.random.default_rng(1)
    n_ratio = 32.0
    Rq = np.diag([45.0, n_ratio])
    Rq[1, 0] = n_ratio
    dq, ddq = rng.normal(size=(9, 2)), rng.normal(size=(9, 2))
    J_m, fv_m, fs_m = 3e-5, 6e-4, 0.06  # motor side
    dq_m, ddq_m = dq @ Rq.T, ddq @ Rq.T
    t_m = J_m * ddq_m[:, 1] + fv_m * dq_m[:, 1] + fs_m * np.sign(dq_m[:, 1])
    tau_joint = np.column_stack([np.zeros(9), t_m]) @ Rq  # tau = Rq^T t (rows: samples)
    terms = ExtraTerms.from_options(
        2, rotor_inertia=False, viscous=False, coulomb=False, offset=False, coupled_wrist=[1, 2]
    )
    Y = extra_columns(terms, dq, ddq)
    joint_side = np.array([n_ratio**2 * J_m, n_ratio**2 * fv_m, n_ratio * fs_m])
    np.testing.assert_allclose(Y @ joint_side, tau_joint, atol=1e-12)


def test_figaroh_basis_is_equivalent():
    # fv_a(fig) = fv_a + fvm, fv_b(fig) = fv_b + fvm, Ia likewise; Iam, fvm, fsm equal.
    rng = np.random.default_rng(2)
    dq, ddq = rng.normal(size=(11, 2)), rng.normal(size=(11, 2))
    terms = ExtraTerms.from_options(2, coulomb=False, offset=False, coupled_wrist=[1, 2])
    names = extra_names(terms)
    assert names == ("Ia1", "fv1", "Ia2", "fv2", "Iam2", "fvm2", "fsm2")
    p = rng.uniform(0.1, 1.0, size=len(names))
    ours = extra_columns(terms, dq, ddq) @ p
    P = dict(zip(names, p, strict=True))
    fig = figaroh_coupling_columns(dq, ddq, (0, 1)) @ np.array([P["Iam2"], P["fvm2"], P["fsm2"]])
    own = np.column_stack(
        [
            (P["Ia1"] + P["Iam2"]) * ddq[:, 0] + (P["fv1"] + P["fvm2"]) * dq[:, 0],
            (P["Ia2"] + P["Iam2"]) * ddq[:, 1] + (P["fv2"] + P["fvm2"]) * dq[:, 1],
        ]
    )
    np.testing.assert_allclose(own + fig, ours, atol=1e-12)


def test_bad_options():
    with pytest.raises(ConfigError, match="joint 7 out of range"):
        ExtraTerms.from_options(6, viscous=[7])
    with pytest.raises(ConfigError, match="coupled_wrist"):
        ExtraTerms.from_options(6, coupled_wrist=[5, 5])
