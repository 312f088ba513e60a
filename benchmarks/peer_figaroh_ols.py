"""FIGAROH's base least squares on a log, in its own process (for ``peer_ur10_truth``).

    python benchmarks/peer_figaroh_ols.py URDF NPZ

``NPZ`` holds the training states and torques (``q``, ``dq``, ``ddq``, ``tau``: (n, nv)) and the
validation states (``qv``, ``dqv``, ``ddqv``). FIGAROH 1.0.2's own functions, as its examples call
them (the ``peers`` extra): the joint-torque regressor of the standard parameters, its zero
columns eliminated, the double QR (base parameters and their OLS values), then the same base
columns on the validation states. Prints one JSON line: the validation torques predicted (n, nv),
the wall time of the fit, the condition number of its base regressor (``cond_num``), and the
number of base parameters. No friction, actuator inertia or offset columns (the UR10 truth has
none).
"""

import json
import sys
import time
import warnings
from types import SimpleNamespace

import numpy as np
import pinocchio as pin

warnings.filterwarnings("ignore")  # FIGAROH 1.0.2's legacy entry points warn on every call
from figaroh.identification.parameter import get_standard_parameters  # noqa: E402
from figaroh.tools.qrdecomposition import (  # noqa: E402
    build_baseRegressor,
    cond_num,
    double_QR,
    get_baseIndex,
)
from figaroh.tools.regressor import (  # noqa: E402
    build_regressor_basic,
    build_regressor_reduced,
    get_index_eliminate,
)


def main(urdf: str, npz: str) -> None:
    d = np.load(npz)
    model = pin.buildModelFromUrdf(urdf)
    robot = SimpleNamespace(model=model, data=model.createData())
    cfg = {
        "has_friction": False,
        "has_actuator_inertia": False,
        "has_joint_offset": False,
        "is_joint_torques": True,
        "act_idxv": list(range(model.nv)),
    }
    t0 = time.perf_counter()
    W = build_regressor_basic(robot, d["q"], d["dq"], d["ddq"], cfg)
    idx_e, params_r = get_index_eliminate(W, get_standard_parameters(model, cfg), 1e-6)
    W_e = build_regressor_reduced(W, idx_e)
    # FIGAROH stacks the rows joint by joint: every sample of joint 1, then of joint 2, ...
    W_b, _, expressions, phi_b = double_QR(d["tau"].T.flatten(), W_e, params_r)
    wall = time.perf_counter() - t0
    idx_base = get_baseIndex(W_e, params_r)
    assert np.abs(build_baseRegressor(W_e, idx_base) - W_b).max() < 1e-9  # same columns
    W_v = build_regressor_reduced(
        build_regressor_basic(robot, d["qv"], d["dqv"], d["ddqv"], cfg), idx_e
    )
    pred = build_baseRegressor(W_v, idx_base) @ phi_b
    n = d["qv"].shape[0]
    print(
        json.dumps(
            {
                "pred": pred.reshape(model.nv, n).T.tolist(),
                "wall_s": wall,
                "cond": float(cond_num(W_b)),
                "n_base": len(expressions),
            }
        )
    )


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
