"""``ident run`` with ``measurement.source: mujoco``: a simulated controller log, identified
like a measured one, reproduced by ``ident identify`` and compared with the simulator's truth.

References: the simulator's truth (URDF inertials + the configured friction and armature) and
``ident identify`` run on the log the run folder keeps.
"""

import json
from pathlib import Path

import mujoco
import numpy as np
import pytest
from robots import UR5_URDF
from typer.testing import CliRunner

from ident.cli import app
from ident.dynamics.friction import ExtraTerms
from ident.dynamics.parameter_model import build_parameter_model
from ident.errors import ConfigError, ModelError
from ident.identify.assessment.rollout import rollout_text
from ident.measure.mujoco_model import (
    inertia_problem,
    load_mujoco,
    mujoco_urdf,
    world_fixed_links,
)
from ident.model import Robot
from ident.run.log_measurement import reference_share
from ident.run.setup import load_run
from ident.trajectory import read_trajectory_csv

REPO = Path(__file__).resolve().parents[1]
QUICK = REPO / "tests" / "data" / "run" / "quick-ur5-mujoco.yaml"
runner = CliRunner()


#: TIAGo's antenna inertial (example-robot-data's tiago.urdf), fixed to the base.
_ANTENNA = """  <link name="antenna"><inertial><mass value="0.000001"/>
    <inertia ixx="2.371e-8" iyy="2.833e-8" izz="3.849e-8"
      ixy="6.119e-8" ixz="1.179e-8" iyz="7.74e-9"/>
  </inertial></link>
  <joint name="antenna_joint" type="fixed"><parent link="base_link"/><child link="antenna"/>
  </joint>
</robot>
"""


def _only(folder: Path) -> Path:
    (path,) = [p for p in folder.iterdir() if p.is_dir()]
    return path


def _errors(result: dict, share_min: float) -> dict[str, float]:
    """Relative error [%] of the chosen elite's base parameters with a torque share >= min."""
    stage = result["stage"]
    chosen = result["chosen_elite"]
    assert chosen is not None, "no safe elite"
    est = result["elites"][chosen - 1]["estimates"]["wls"]
    out = {}
    for name, true, value, share in zip(
        stage["base_names"],
        stage["true_base"],
        est["x"],
        stage["reference_torque_share"],
        strict=True,
    ):
        if share >= share_min:
            out[name] = 100.0 * abs(value - true) / abs(true)
    return out


@pytest.fixture(scope="module")
def quick_run(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("runs")
    config = out.parent / "quick-ur5-mujoco.yaml"
    config.write_text(_quick_without_collision_checks())  # none of its tests is about them
    result = runner.invoke(app, ["run", str(config), "--out", str(out), "--no-replay"])
    assert result.exit_code == 0, result.output
    (out / "terminal.txt").write_text(result.output)  # beside the run folder
    return _only(out)


def _quick_without_collision_checks() -> str:
    """QUICK's text, robot paths absolute, without the floor and self-collision checks: for
    the tests of a run's failure paths (a joint below its threshold, a failed simulation),
    which the mesh distances at 1 kHz do not touch (measured: most of such a run's CPU)."""
    text = QUICK.read_text().replace("../../../robot", str(REPO / "robot"))
    for old, new in (
        ("floor: {enabled: true, z: 0.0}", "floor: {enabled: false, z: 0.0}"),
        ("self_collision: true", "self_collision: false"),
    ):
        assert old in text
        text = text.replace(old, new)
    return text


def test_identify_on_the_run_folder_log_gives_the_runs_estimate(quick_run, tmp_path) -> None:
    identify_yaml = quick_run / "elites" / "elite_1" / "identify.yaml"
    assert (quick_run / "elites" / "elite_1" / "log.csv").is_file()
    result = runner.invoke(
        app, ["identify", str(identify_yaml), "--out", str(tmp_path), "--no-replay"]
    )
    assert result.exit_code == 0, result.output
    again = json.loads((_only(tmp_path) / "result.json").read_text())
    run = json.loads((quick_run / "result.json").read_text())
    x_run = np.array(run["elites"][0]["estimates"]["wls"]["x"])
    x_identify = np.array([p["value"] for p in again["base_parameters"]])
    assert [p["name"] for p in again["base_parameters"]] == run["stage"]["base_names"]
    np.testing.assert_allclose(x_identify, x_run, rtol=1e-12, atol=0.0)
    # both write the identified model of this log (the run: of the executed elite, here 1),
    # the same consistent LMI estimate: the same URDF and MJCF (the run names the files
    # after the config's URDF, identify after the run folder's copy, robot.urdf)
    model, model_again = run["model"], again["model"]
    assert model["elite"] == run["executed_elite"] == 1
    assert model["method"] == model_again["method"] == "lmi"
    assert max(model["reload_parity"][k] for k in ("urdf", "mjcf")) <= 1e-9
    assert model["files"]["urdf"] == "ur5_identified.urdf"
    for key in ("urdf", "mjcf"):
        ours = (quick_run / model["files"][key]).read_text()
        theirs = (_only(tmp_path) / model_again["files"][key]).read_text()
        assert ours == theirs, key
    # the run's coverage of the truth by the 95 % intervals = the re-identification's, whose
    # intervals and truth (validation.truth) are both in its result.json
    unc = again["uncertainty"]
    lo_hi = np.array([p["interval_95"] for p in unc["parameters"]])
    true = np.array(run["stage"]["true_base"])
    inside = np.mean((lo_hi[:, 0] <= true) & (true <= lo_hi[:, 1]))
    est = run["elites"][0]["estimates"]["wls"]
    assert est["within_95_interval"] == pytest.approx(inside)
    assert unc["truth_inside"][unc["method"]] == pytest.approx(inside)
    assert (
        f"{100 * inside:.0f} % inside their 95 % interval" in (quick_run / "report.md").read_text()
    )
    # the same MJCF on the same held-out windows: the same rollout score; identify's reference
    # is the URDF nominal (no rotor inertia, no friction): far worse than the identified MJCF
    rollout, rollout_again = run["rollout"], again["rollout"]
    assert rollout_again["objective"] == pytest.approx(rollout["objective"], rel=1e-9)
    assert rollout_again["reference"] == "nominal"
    assert rollout_again["reference_objective"] > 100.0 * rollout_again["objective"]


def test_the_identified_mjcf_rollout_is_shown_beside_the_truths(quick_run) -> None:
    """One entry in result.json, its line in the report's summary and in the terminal: the
    identified MJCF replays the held-out log open loop about as well as the truth's MJCF
    (measured: 1.1e-4 and 8.8e-5, 4 windows of 0.5 s); J ~ 1 would be errors as large as the
    motion."""
    rollout = json.loads((quick_run / "result.json").read_text())["rollout"]
    assert rollout["reference"] == "truth"
    assert rollout["note"] is None
    assert rollout["reference_note"] is None
    assert rollout["window_s"] == 0.5
    assert 1 <= rollout["windows"] <= rollout["max_windows"] == 64
    assert rollout["held_out"] is True
    assert 0.0 < rollout["objective"] < 1e-2
    assert 0.0 < rollout["reference_objective"] < 1e-2
    text = rollout_text(rollout)
    assert f"| MJCF rollout | {text} |" in (quick_run / "report.md").read_text()
    terminal = (quick_run.parent / "terminal.txt").read_text().replace("│", " ")
    assert f"MJCF rollout error {rollout['objective']:.3g}" in " ".join(terminal.split())


def test_friction_and_rotor_inertia_are_recovered_from_the_simulated_log(quick_run) -> None:
    run = json.loads((quick_run / "result.json").read_text())
    stage = run["stage"]
    truth = dict(zip(stage["base_names"], stage["true_base"], strict=True))
    # the configured friction is the truth the log carries
    assert (truth["fv1"], truth["fs3"], truth["Ia3"]) == pytest.approx((3.0, 3.0, 0.3))
    errors = _errors(run, 0.0)
    extras = {n: e for n, e in errors.items() if n[:2] in ("fv", "fs")}
    assert len(extras) == 12
    assert max(extras.values()) < 10.0, extras  # a 2-iteration design; the full configs: 5 %


def test_mujoco_needs_every_joint_moving_and_one_value_per_joint(tmp_path) -> None:
    text = QUICK.read_text().replace("../../../robot", str(REPO / "robot"))
    held = tmp_path / "held.yaml"
    held.write_text(
        text + "stage: {moving: [shoulder_pan_joint, shoulder_lift_joint, elbow_joint]}\n"
    )
    with pytest.raises(ConfigError, match="every joint must move"):
        load_run(held)
    short = tmp_path / "short.yaml"
    short.write_text(
        text.replace("armature: [0.5, 0.5, 0.3, 0.05, 0.05, 0.05]", "armature: [1, 2]")
    )
    with pytest.raises(ConfigError, match="armature"):
        load_run(short)
    # a link whose inertia has products and a negative principal moment (TIAGo's 1 mg
    # antennas): on a moving link refused by the loader, naming the link, before any design
    # (the robot's inertia check first; MuJoCo's own refusal named by inertia_problem)
    ur5 = (REPO / "robot" / "urdf" / "ur5.urdf").read_text()
    moving = ur5.replace("</robot>", _ANTENNA.replace('link="base_link"', 'link="wrist_3_link"'))
    (tmp_path / "moving.urdf").write_text(moving)
    on_wrist = tmp_path / "moving.yaml"
    on_wrist.write_text(text.replace(str(REPO / "robot" / "urdf" / "ur5.urdf"), "moving.urdf"))
    with pytest.raises(ModelError, match="link 'antenna'"):
        load_run(on_wrist)
    assert "link 'antenna' (" in inertia_problem(moving, "x")
    # fixed to the world (as TIAGo's, on its base): left out of the simulation and named
    urdf = ur5.replace("</robot>", _ANTENNA)
    (tmp_path / "antenna.urdf").write_text(urdf)
    antenna = tmp_path / "antenna.yaml"
    antenna.write_text(text.replace(str(REPO / "robot" / "urdf" / "ur5.urdf"), "antenna.urdf"))
    setup = load_run(antenna)
    (note,) = setup.simulation_notes
    assert "'antenna'" in note
    assert "left out of the MuJoCo simulation" in note
    assert inertia_problem(urdf, "x") == ""
    # reference: MuJoCo itself refuses that inertia (kept on the moving link), and takes it
    # with the products set to 0; the simulated model equals the one without the antenna
    with pytest.raises(ValueError, match="positive eigenvalues"):
        mujoco.MjSpec.from_string(mujoco_urdf(moving, {}, "x")).compile()
    fixed = moving.replace('ixy="6.119e-8" ixz="1.179e-8" iyz="7.74e-9"', 'ixy="0" ixz="0" iyz="0"')
    mujoco.MjSpec.from_string(mujoco_urdf(fixed, {}, "antenna")).compile()
    assert inertia_problem(fixed, "fixed") == ""
    sim = load_mujoco(setup.robot).model
    plain = load_mujoco(Robot.from_urdf(REPO / "robot" / "urdf" / "ur5.urdf")).model
    assert np.array_equal(sim.body_mass, plain.body_mass)
    assert np.array_equal(sim.body_inertia, plain.body_inertia)
    # a lock makes the links it holds fixed to the world; a moving joint does not
    assert world_fixed_links(ur5) == {"world", "base_link", "base"}
    assert "shoulder_link" in world_fixed_links(ur5, {"shoulder_pan_joint": 0.0})


@pytest.mark.slow
@pytest.mark.parametrize("name", ["ur5", "panda"])
def test_shipped_robot_configs_identify_within_5_percent(name, shipped_run) -> None:
    """Every base parameter with >= 1 % of the torques within 5 %, the
    friction and rotor inertias within 5 %, from MuJoCo data with friction, armature, noise."""
    run = json.loads((shipped_run(name) / "result.json").read_text())
    major = _errors(run, 0.01)
    assert max(major.values()) < 5.0, major
    extras = {n: e for n, e in _errors(run, 0.0).items() if n[:2] in ("fv", "fs", "Ia")}
    assert max(extras.values()) < 5.0, extras


def test_torque_share_is_filled_and_matches_pinocchio_and_closed_form_friction(quick_run) -> None:
    """The report's "torque share" of a simulated-log run, against an independent reference.

    Reference: the true torque of the elite's designed trajectory is Pinocchio's RNEA on the
    run's URDF plus ``fv dq + fs sign(dq) + Ia ddq`` (the configured truth), and the viscous
    column of joint j is ``dq_j`` on row j, so ``share(fv_j) = fv_j ||dq_j|| / ||tau||``.
    (It was empty on every URDF robot: only the ideal measurement stored the column norms.)
    """
    import pinocchio as pin

    from ident.report.format import fmt

    run = json.loads((quick_run / "result.json").read_text())
    stage = run["stage"]
    est = run["elites"][0]["estimates"]["wls"]
    share = dict(zip(stage["base_names"], est["torque_share"], strict=True))
    assert all(v is not None for v in share.values()), share
    header = (quick_run / "elites" / "elite_1.csv").read_text().splitlines()[0].split(",")
    data = np.loadtxt(quick_run / "elites" / "elite_1.csv", delimiter=",", skiprows=1)
    q, dq, ddq = (
        data[:, [k for k, h in enumerate(header) if h.startswith(p)]] for p in ("q_", "dq_", "ddq_")
    )
    model = pin.buildModelFromUrdf(str(quick_run / "robot.urdf"))
    pdata = model.createData()
    fv = np.array([3.0, 3.0, 2.0, 0.5, 0.5, 0.5])
    fs = np.array([5.0, 5.0, 3.0, 1.0, 1.0, 1.0])
    armature = np.array([0.5, 0.5, 0.3, 0.05, 0.05, 0.05])
    tau = np.array([pin.rnea(model, pdata, *s).copy() for s in zip(q, dq, ddq, strict=True)])
    tau += fv * dq + fs * np.sign(dq) + armature * ddq
    expected = fv * np.linalg.norm(dq, axis=0) / np.linalg.norm(tau)
    got = np.array([share[f"fv{j + 1}"] for j in range(6)])
    np.testing.assert_allclose(got, expected, rtol=1e-6)
    # the report renders the column from these values (percent, never empty)
    report = (quick_run / "report.md").read_text()
    assert f"| {fmt(100 * share['fv1'], 2)} | yes |" in report


def _statuses(run: Path) -> tuple[tuple[str, str], tuple[str, str]]:
    state = json.loads((run / "run.json").read_text())
    data = json.loads((run / "result.json").read_text())
    return (state["status"], state["message"]), (data["status"], data["message"])


@pytest.mark.slow
def test_a_joint_below_its_velocity_threshold_is_named_with_the_field(tmp_path) -> None:
    """wrist_3's velocity threshold at 100 rad/s: no sample reaches it, WLS fails. The run
    ends with exit 1 and a terminal line naming the joint, its speed and the run config's
    field (it ended with exit 2 on 'elites/elite_1.csv: non-finite value in column tau_...',
    the run's own file, with run.json incomplete and result.json complete). The speed named
    is the elite's (its commanded velocity, elites/elite_1.csv, tracked by the simulated
    controller), and the simulated log is kept for 'ident identify'."""
    text = _quick_without_collision_checks()
    config = tmp_path / "idle.yaml"
    config.write_text(
        text.replace("0.05, 0.05, 0.05, 0.05, 0.05, 0.05]", "0.05, 0.05, 0.05, 0.05, 0.05, 100]")
    )
    result = runner.invoke(
        app, ["run", str(config), "--out", str(tmp_path / "runs"), "--no-replay"]
    )
    assert result.exit_code == 1, result.output
    (line,) = [x for x in result.stderr.splitlines() if x.startswith("error: elite 1, wls: ")]
    speed = float(line.split("wrist_3_joint moves at most ")[1].split(" rad/s")[0])
    assert (
        "below its identification.preprocess.velocity_threshold of 100 rad/s (entry 6 of 6)" in line
    )
    run = _only(tmp_path / "runs")
    elite = read_trajectory_csv(run / "elites" / "elite_1.csv")  # readable: finite torques
    assert elite.tau is not None
    assert np.isfinite(elite.tau).all()
    assert speed == pytest.approx(np.abs(elite.dq[:, 5]).max(), rel=0.1)
    assert (run / "elites" / "elite_1" / "identify.yaml").is_file()
    state, saved = _statuses(run)
    assert state == saved == ("complete", "run complete")


def test_a_failed_simulation_leaves_no_torques_and_names_its_cause(tmp_path, monkeypatch) -> None:
    """The simulator failing for an elite: its CSV has the commanded motion and no tau_*
    columns (they were NaN, which the replay then refused with exit 2), the terminal names
    the simulator's message, the replay is written, and both status files agree."""
    import ident.run.log_measurement as log_measurement
    from ident.errors import DataError

    def diverges(*args, **kwargs):
        raise DataError("the computed-torque controller diverged at t = 1.25 s (test)")

    monkeypatch.setattr(log_measurement, "simulate", diverges)
    text = _quick_without_collision_checks()
    config = tmp_path / "diverging.yaml"
    config.write_text(text)
    result = runner.invoke(app, ["run", str(config), "--out", str(tmp_path / "runs")])
    assert result.exit_code == 1, result.output
    assert (
        "error: elite 1, wls: the simulation of elite 1 failed, nothing was measured: the "
        "computed-torque controller diverged at t = 1.25 s (test)" in result.stderr
    )
    run = _only(tmp_path / "runs")
    header = (run / "elites" / "elite_1.csv").read_text().splitlines()[0]
    assert "tau_" not in header
    assert "dq_wrist_3_joint" in header
    assert (run / "replay.html").is_file()
    state, saved = _statuses(run)
    assert state == saved == ("complete", "run complete")


def test_major_parameters_are_judged_at_the_robots_own_acceleration_limits() -> None:
    """The reference torque share (which parameters are *major* for the verdict) is taken on
    random states within the limits the run keeps, its acceleration limits included.

    Closed form: joint j's rotor-inertia column is ``ddq_j`` and its viscous column ``dq_j``
    (both "alone" on row j), and the uniform accelerations scale with the limit, so limiting
    every joint to 1 rad/s^2 instead of the default 10 divides ``share(Ia_j) / share(fv_j)``
    by exactly 10. (The shares were taken at 10 rad/s^2 whatever the robot's limits: a Kinova
    limited to 1.9 rad/s^2 had its rotor and wrist inertias judged "major".)
    """
    robot = Robot.from_urdf(UR5_URDF)
    terms = ExtraTerms.from_options(robot.nv, coulomb=False, offset=False)
    pm = build_parameter_model(robot.model, terms)
    truth = np.array(pm.nominal, dtype=float)
    index = {n: i for i, n in enumerate(pm.names)}
    for j in range(robot.nv):
        truth[index[f"Ia{j + 1}"]], truth[index[f"fv{j + 1}"]] = 0.1, 1.0
    base = {n: i for i, n in enumerate(pm.base.base_names)}
    alone = [j for j in range(robot.nv) if f"Ia{j + 1}" in base]  # Ia1 joins Izz1R
    assert len(alone) >= 4
    ia, fv = [[base[f"{k}{j + 1}"] for j in alone] for k in ("Ia", "fv")]
    default = reference_share(pm, truth, robot)  # no acceleration limit known: 10 rad/s^2
    robot.ddq_max = np.full(robot.nv, 1.0)
    limited = reference_share(pm, truth, robot)
    np.testing.assert_allclose(
        limited[ia] / limited[fv], 0.1 * default[ia] / default[fv], rtol=1e-9
    )
