"""``ident init`` on large meshes and branched robots: the self-collision settlement measures
the exact meshes only where the convex hulls are close (a bounded number of exact calls, the
same margin as exact distances give), and the config written for Baxter's left arm keeps every
design within the position ranges, says why each joint is locked and names the chain's tip."""

from __future__ import annotations

import coal
import numpy as np
import pinocchio as pin
import pytest
import yaml
from robots import ERD_ROBOTS, UR5_URDF

from ident.excitation import safety as safety_module
from ident.excitation.fourier import fourier_bound_factors
from ident.model.selection import RobotSelection, load_robot
from ident.run.init_config import init_config

BAXTER = ERD_ROBOTS / "baxter_description/urdf/baxter.urdf"


def _count_exact_mesh_calls(monkeypatch) -> dict[str, int]:
    """Count pinocchio's distance and collision calls on a pair with a mesh (BVH) side."""
    counts = {"exact": 0}

    def is_mesh_pair(geom, index):
        pair = geom.collisionPairs[index]
        return any(
            isinstance(geom.geometryObjects[g].geometry, coal.BVHModelBase)
            for g in (pair.first, pair.second)
        )

    def wrap(name):
        original = getattr(pin, name)

        def counted(*args):
            if name == "computeCollisions":  # every pair of the geometry at once
                geom = args[2]
                counts["exact"] += sum(
                    is_mesh_pair(geom, k) for k in range(len(geom.collisionPairs))
                )
            elif is_mesh_pair(args[0], args[2]):
                counts["exact"] += 1
            return original(*args)

        monkeypatch.setattr(pin, name, counted)

    for name in ("computeDistance", "computeCollision", "computeCollisions"):
        wrap(name)
    return counts


def test_margin_settlement_measures_meshes_a_bounded_number_of_times(monkeypatch):
    # UR5: three link pairs never 3 cm apart; the default margin is halved to 7.5 mm. Measured
    # once per posture and pair where the hulls are close (not once per halving), the exact
    # mesh calls stay below one pass over every pair and posture (the old per-halving
    # collisions made five such passes)
    package = ERD_ROBOTS.parents[1]
    robot = load_robot(RobotSelection(urdf=UR5_URDF, package_dirs=[package]), source=UR5_URDF)
    safety_module._SCREENED.clear()
    counts = _count_exact_mesh_calls(monkeypatch)
    model = safety_module.build_safety_model(
        robot, {"floor": {"enabled": False}}, package_dirs=[package], lower_margin=True
    )
    monkeypatch.undo()
    n_postures = model.postures.shape[0]
    tested = len(model.keepable_clearances)
    assert counts["exact"] <= n_postures * tested // 2, counts
    # the same margin as exact distances give: each close pair's largest clearance over the
    # postures, from coal on the meshes at every posture (an independent pass)
    close = {k: v for k, v in model.keepable_clearances.items() if v < 0.03}
    assert {tuple(sorted(k)) for k in close} == {
        ("base_link", "upper_arm_link"),
        ("forearm_link", "wrist_2_link"),
        ("wrist_1_link", "wrist_3_link"),
    }
    geom = model.exact_geometry_model.clone()
    names = [model.model.frames[o.parentFrame].name for o in geom.geometryObjects]
    geom.removeAllCollisionPairs()
    for a in range(len(names)):
        for b in range(a + 1, len(names)):
            if tuple(sorted((names[a], names[b]))) in close:
                geom.addCollisionPair(pin.CollisionPair(a, b))
    data, gdata = model.model.createData(), pin.GeometryData(geom)
    largest = dict.fromkeys(close, -np.inf)
    for q in model.postures:
        pin.computeDistances(model.model, data, geom, gdata, q)
        for pair, result in zip(geom.collisionPairs, gdata.distanceResults, strict=True):
            key = tuple(sorted((names[pair.first], names[pair.second])))
            largest[key] = max(largest[key], result.min_distance)
    for key, value in close.items():
        assert value == pytest.approx(largest[key], abs=1e-6)
    margin = 0.03
    while min(largest.values()) < margin:
        margin /= 2.0
    assert model.clearance_m == pytest.approx(margin)


@pytest.fixture(scope="module")
def baxter(tmp_path_factory):
    out = tmp_path_factory.mktemp("baxter") / "baxter.yaml"
    result = init_config(BAXTER, out)
    return result, yaml.safe_load(result.text)


def test_baxter_box_keeps_every_joint_within_its_position_range(baxter):
    _, config = baxter
    model = pin.buildModelFromUrdf(str(BAXTER))  # the limits, read independently
    options = config["excitation"]["options"]
    c_q, _, _ = fourier_bound_factors(options["n_harmonics"])
    w = options["base_frequency"]
    bounds = config["excitation"]["bounds"]
    names = [n for n in model.names[1:] if n.startswith("left_") and f"q0[{n}]" in bounds]
    assert len(names) == 7
    amplitude = dict(zip(names, options["amplitude_bound"], strict=True))
    for name in names:
        idx = model.joints[model.getJointId(name)].idx_q
        lower, upper = model.lowerPositionLimit[idx], model.upperPositionLimit[idx]
        low, high = bounds[f"q0[{name}]"]
        swing = c_q * amplitude[name] / w  # |q - q0| of any design of the box
        assert low <= high
        assert low - swing >= lower, name
        assert high + swing <= upper, name


def test_baxter_period_frees_the_box_from_its_short_ranges(baxter):
    # at 10 s the +-1.7 rad ranges capped the box at a fraction of the acceleration limits;
    # the period where the position term 0.7 h w / c_q of the amplitude bound stops binding on
    # 3/4 of the joints (h from Pinocchio's limits) lets those joints' box reach their
    # velocity or acceleration limit
    result, config = baxter
    model = pin.buildModelFromUrdf(str(BAXTER))
    options = config["excitation"]["options"]
    c_q, _, _ = fourier_bound_factors(options["n_harmonics"])
    w = options["base_frequency"]
    period = 2.0 * np.pi / w
    assert 3.0 < period < 6.0
    # the period and why, in init's notes and beside base_frequency
    note = next(n for n in result.notes if n.startswith("excitation: period"))
    assert f"period {period:.3g} s, shorter than 10 s" in note
    assert "stop binding the box on 75% of the joints" in result.text
    names = [
        n
        for n in model.names[1:]
        if n.startswith("left_") and f"q0[{n}]" in config["excitation"]["bounds"]
    ]
    free = 0
    for name, amplitude in zip(names, options["amplitude_bound"], strict=True):
        idx = model.joints[model.getJointId(name)].idx_q
        span = model.upperPositionLimit[idx] - model.lowerPositionLimit[idx]
        room = 0.5 * span - min(0.05, 0.05 * span)
        free += amplitude < 0.999 * 0.7 * room * w / c_q
    assert free >= 5, free
    # as many logged samples as three 10 s periods
    n_periods = config["measurement"]["n_periods"]
    assert n_periods * period >= 30.0 > (n_periods - 1) * period


def test_baxter_locks_tip_and_margin_say_why(baxter):
    result, config = baxter
    notes = "\n".join(result.notes)
    head = next(n for n in result.notes if n.startswith("lock: head_pan"))
    assert "finger" not in head
    assert "not on the chain" in head
    assert "left_wrist" in head
    finger = next(n for n in result.notes if "l_gripper_l_finger_joint" in n)
    assert "gripper finger" in finger
    right = next(n for n in result.notes if "right_s0" in n)
    assert "not on the chain" in right
    # the chain's tip is written: the replay traces it, not the head's sonar ring
    assert config["robot"]["tip_link"] == "left_wrist"
    # a margin below 1 cm names the pair that forces it and the SRDF line that would free it
    assert config["safety"]["clearance_m"] < 0.01
    assert '<disable_collisions link1="left_upper_elbow" link2="left_upper_shoulder"' in notes
