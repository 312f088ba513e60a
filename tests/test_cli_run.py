import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from ident.cli import app

QUICK = Path(__file__).parent / "data" / "run" / "quick-wrist.yaml"
runner = CliRunner()


def _run(*args):
    return runner.invoke(app, ["run", *map(str, args)])


def _only_run_dir(out):
    dirs = [d for d in out.iterdir() if d.is_dir()]
    assert len(dirs) == 1
    return dirs[0]


def _statuses(run_dir):
    """(status, message) of run.json and of result.json: they must be the same pair."""
    state = json.loads((run_dir / "run.json").read_text())
    data = json.loads((run_dir / "result.json").read_text())
    return (state["status"], state["message"]), (data["status"], data["message"])


@pytest.fixture(scope="module")
def quick_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("runs")
    result = _run(QUICK, "--out", out)
    assert result.exit_code == 0, result.output
    return out, _only_run_dir(out), result.output


def test_quick_run_writes_every_file(quick_run):
    _, run_dir, output = quick_run
    assert run_dir.name.startswith("quick-wrist-")
    for name in (
        "run.json",
        "config.yaml",
        "robot.urdf",
        "result.json",
        "trajectory.csv",
        "elites/elite_1.csv",
        "elites/elite_2.csv",
        "figures/convergence.png",
        "figures/trajectory.png",
        "report.md",
        "report.html",
        "replay.html",
    ):
        assert (run_dir / name).is_file(), name
    state, result = _statuses(run_dir)
    assert state == result == ("complete", "run complete")
    assert not (run_dir / "INCOMPLETE").exists()
    assert f"Report: {run_dir / 'report.html'}" in output
    assert f"Run folder: {run_dir}" in output


def test_an_ideal_measurement_names_the_rollout_check_it_cannot_run(quick_run):
    """No simulated log, no MJCF: the rollout check says so in result.json, the report's
    summary and the terminal."""
    _, run_dir, output = quick_run
    rollout = json.loads((run_dir / "result.json").read_text())["rollout"]
    assert rollout["objective"] is None
    assert rollout["note"] == (
        "rollout check not run: no simulated log (measurement.source: ideal), so no MJCF is written"
    )
    assert f"| MJCF rollout | {rollout['note']} |" in (run_dir / "report.md").read_text()
    assert "rollout check not run" in " ".join(output.replace("│", " ").split())


def test_result_json_is_complete_and_exact(quick_run):
    _, run_dir, _ = quick_run
    data = json.loads((run_dir / "result.json").read_text())
    assert data["status"] == "complete"
    stage = data["stage"]
    n_base = stage["counts"]["n_base"]
    assert n_base == len(stage["base_names"]) == len(stage["true_base"])
    c = stage["counts"]
    assert c["independent"] + c["dependent"] + c["unidentifiable"] == 30
    assert stage["paper_counts"] == {"independent": 15, "dependent": 7, "unidentifiable": 8}
    best = data["elites"][0]
    assert best["fitness"] is not None
    for method in ("ols", "wls"):
        est = best["estimates"][method]
        assert len(est["x"]) == len(est["std"]) == n_base
        assert est["condition_number"] > 1
        assert est["max_rel_error"] < 1e-8  # noise-free
        assert est["max_torque_error"] < 1e-8
        assert len(est["torque_share"]) == n_base
    assert "noise-free" in best["estimates"]["wls"]["message"]
    assert len(data["optimization"]["runs"]) == 2


def test_the_evaluation_budget_printed_is_what_the_optimizer_counted(quick_run):
    """The terminal and report.md state runs x populations x particles = evaluations; the
    total is the optimizer's own count (nfev) of every run (2 x 7 x 8 = 112: a budget
    without the initial population, 2 x 6 x 8 = 96, would differ)."""
    _, run_dir, output = quick_run
    data = json.loads((run_dir / "result.json").read_text())
    counted = sum(r["nfev"] for r in data["optimization"]["runs"])
    text = (
        f"2 run(s) x 7 populations (initial + 6 iterations) x 8 particles = {counted} evaluations"
    )
    assert text in (run_dir / "report.md").read_text()
    assert text in " ".join(output.replace("│", " ").split())  # the table wraps the cell


def test_report_is_self_contained_and_mentions_the_paper(quick_run):
    _, run_dir, _ = quick_run
    page = (run_dir / "report.html").read_text()
    assert page.count("data:image/png;base64,") >= 3
    assert 'href="replay.html"' in page
    md = (run_dir / "report.md").read_text()
    assert "Tables 2-3" in md
    assert "| paper (its 6R robot, DH frames) | 15 | 7 | 8 |" in md
    assert "nan" not in md.lower().replace("nanosecond", "")


def test_report_compares_dh_frame_counts_with_an_independent_computation(quick_run):
    """The report's DH-frame counts are those of compute_base_parameters on W @ M (own
    random states of the stage), and the paper's names are placed in our DH classes."""
    from ident.dynamics.base_parameters import compute_base_parameters
    from ident.dynamics.stage import paper_stages
    from ident.model import Robot

    _, run_dir, _ = quick_run
    data = json.loads((run_dir / "result.json").read_text())
    robot = Robot.from_config(QUICK.parents[3] / "configs" / "paper6r.yaml")
    stage = paper_stages(robot.chain)["wrist"]  # the joint_fourier family holds the arm here
    gen = np.random.default_rng(123)
    n = 300
    q = np.tile(np.asarray(stage.held_positions), (n, 1))
    dq, ddq = np.zeros((n, 6)), np.zeros((n, 6))
    moving = list(stage.moving_joints)
    q[:, moving] = gen.uniform(robot.q_lower[moving], robot.q_upper[moving], (n, 3))
    dq[:, moving] = gen.uniform(-1.0, 1.0, (n, 3)) * robot.dq_max[moving]
    ddq[:, moving] = gen.uniform(-1.0, 1.0, (n, 3)) * robot.ddq_max[moving]
    Y = robot.regressor(q, dq, ddq)[:, list(stage.torque_rows), :] @ robot.dh_to_model_parameters()
    cols = list(stage.columns)
    W = Y[:, :, cols].reshape(-1, len(cols))
    names = [robot.parameter_names()[c] for c in cols]
    ref = compute_base_parameters(W, names, method="qr").counts()
    dh = data["stage"]["dh_frames"]
    assert dh["frames"] == "DH"
    assert (
        dh["counts"]["independent"],
        dh["counts"]["dependent"],
        dh["counts"]["unidentifiable"],
    ) == (ref["n_independent"], ref["n_dependent"], ref["n_unidentifiable"])
    assert (ref["n_independent"], ref["n_dependent"], ref["n_unidentifiable"]) == (17, 5, 8)
    unidentifiable = {names[i] for i in compute_base_parameters(W, names).unidentifiable}
    assert set(dh["unidentifiable"]) == unidentifiable
    # the true DH base parameters are the projection of Robot.parameters_dh()
    assert dh["true_standard"] == pytest.approx(
        robot.parameters_dh()[[robot.parameter_names().index(n) for n in dh["standard_names"]]],
        rel=1e-12,
        abs=1e-15,
    )
    md = (run_dir / "report.md").read_text()
    assert "| this run, DH frames (the paper's frames) | 17 | 5 | 8 |" in md
    assert "| this run, body frames (the estimate) | 17 | 4 | 9 |" in md
    # paper-notes: Iyy4 and m6 are unidentifiable only because of the body frames
    rows = {r["name"]: r for r in data["stage"]["paper_comparison"]}
    assert rows["Iyy4"]["body"] == "unidentifiable"
    assert rows["Iyy4"]["dh"] == "independent"
    assert rows["m6"]["body"] == "unidentifiable"
    assert rows["m6"]["dh"] == "dependent"
    assert rows["Iyy4"]["paper"] == ["independent"]
    assert rows["Ixz4"]["paper"] == ["independent"]
    assert rows["Ixz4"]["dh"] == "unidentifiable"
    assert rows["Iyz6"]["paper"] == ["independent", "dependent"]
    assert "| `Iyy4` | independent | independent | unidentifiable |" in md


def test_replay_traces_the_stage_point_and_names_it(quick_run, tmp_path):
    """Wrist (joint-space family, no traced frame of its own): the flange; the arm stage:
    the wrist centre. The frame reaches replay_html (its caption) and the note printed."""
    from ident.report.run_report import write_replay

    _, run_dir, output = quick_run
    assert "traced frame: flange" in output
    page = (run_dir / "replay.html").read_text()
    assert "traced frame flange" in page
    assert "elite 1 of quick-wrist (wrist stage)" in page
    arm = tmp_path / "arm"
    shutil.copytree(run_dir, arm)
    (arm / "replay.html").unlink()
    data = json.loads((arm / "result.json").read_text())
    data["config"]["stage"] = "arm"
    (arm / "result.json").write_text(json.dumps(data))
    assert write_replay(arm) == "replay.html written (traced frame: wrist_centre)."
    page = (arm / "replay.html").read_text()
    assert "traced frame wrist_centre" in page
    assert "elite 1 of quick-wrist (arm stage)" in page


def test_same_seed_gives_byte_identical_result_json(quick_run, tmp_path):
    _, run_dir, _ = quick_run
    result = _run(QUICK, "--out", tmp_path, "--no-replay")
    assert result.exit_code == 0, result.output
    again = _only_run_dir(tmp_path)
    assert again != run_dir
    assert (again / "result.json").read_bytes() == (run_dir / "result.json").read_bytes()
    assert not (again / "replay.html").exists()


def test_report_command_regenerates(quick_run, tmp_path):
    _, run_dir, _ = quick_run
    copy = tmp_path / run_dir.name
    shutil.copytree(run_dir, copy)
    for name in ("report.md", "report.html", "figures/convergence.png"):
        (copy / name).unlink()
    result = runner.invoke(app, ["report", str(copy)])
    assert result.exit_code == 0, result.output
    assert (copy / "report.html").is_file()
    assert (copy / "figures/convergence.png").is_file()
    assert (copy / "report.md").read_text() == (run_dir / "report.md").read_text()


def test_report_on_a_non_run_folder_is_a_clear_error(tmp_path):
    result = runner.invoke(app, ["report", str(tmp_path)])
    assert result.exit_code == 2
    assert "run.json" in result.output


def test_ctrl_c_leaves_a_consistent_incomplete_folder(tmp_path, monkeypatch):
    from ident.cli import run as cli_run

    original = cli_run._ProgressDisplay.update

    def interrupt(self, event):
        original(self, event)
        if event.phase == "run_done":
            raise KeyboardInterrupt

    monkeypatch.setattr(cli_run._ProgressDisplay, "update", interrupt)
    result = _run(QUICK, "--out", tmp_path)
    assert result.exit_code == 130
    run_dir = _only_run_dir(tmp_path)
    state = json.loads((run_dir / "run.json").read_text())
    assert state["status"] == "incomplete"
    assert "interrupted" in state["message"]
    assert (run_dir / "INCOMPLETE").is_file()
    data = json.loads((run_dir / "result.json").read_text())
    assert data["status"] == "incomplete"
    assert data["optimization"]["n_runs_finished"] == 1
    assert data["elites"] == []
    assert "Incomplete run" in (run_dir / "report.md").read_text()


def test_bad_config_is_one_line_exit_2(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text(QUICK.read_text().replace("stage: wrist", "stag: wrist"))
    result = _run(bad, "--out", tmp_path / "runs")
    assert result.exit_code == 2
    assert "did you mean 'stage'" in result.output
    assert "Traceback" not in result.output
    assert not (tmp_path / "runs").exists()


@pytest.mark.parametrize(
    ("bounds", "expected"),
    [
        # a typo of a joint-space Fourier variable: the closest name is suggested
        ("{'q0[joint_44]': [0, 1]}", "did you mean 'q0[joint_4]'?"),
        # nothing alike: still the nearest name and the whole list
        ("{zz: [0, 1]}", "nearest: '"),
        ("{'q0[joint_4]': [1, 0]}", "low < high"),
        ("{'q0[joint_4]': [0, .inf]}", "finite"),
        ("{'q0[joint_4]': [.nan, 1]}", "finite"),
    ],
)
def test_bad_excitation_bounds_stop_before_the_run_folder(tmp_path, bounds, expected):
    bad = tmp_path / "bounds.yaml"
    text = QUICK.read_text().replace(
        "robot: ../../../configs/paper6r.yaml",
        f"robot: {QUICK.parents[3] / 'configs/paper6r.yaml'}",
    )
    bad.write_text(text.replace("n_samples: 100\n", f"n_samples: 100\n  bounds: {bounds}\n"))
    result = _run(bad, "--out", tmp_path / "runs", "--quick")
    assert result.exit_code == 2, result.output
    lines = result.output.strip().splitlines()
    assert len(lines) == 1, result.output
    line = lines[0]
    assert line.startswith(f"error: {bad}: "), line
    assert "excitation.bounds." in line
    assert expected in line
    if "low < high" not in expected and "finite" not in expected:
        assert "Variables: q0[joint_4], a2[joint_4]" in line
    assert "Traceback" not in result.output
    assert not (tmp_path / "runs").exists()  # no run folder, not even an empty one


def test_unmeetable_limits_exit_2_before_any_folder(tmp_path):
    bad = tmp_path / "infeasible.yaml"
    text = QUICK.read_text().replace(
        "robot: ../../../configs/paper6r.yaml",
        f"robot: {QUICK.parents[3] / 'configs/paper6r.yaml'}",
    )
    text = text.replace(
        "n_samples: 100\n", "n_samples: 100\n  bounds: {'q0[joint_5]': [3.0, 3.1]}\n"
    )
    bad.write_text(text)
    result = _run(bad, "--out", tmp_path / "runs")
    assert result.exit_code == 2
    (line,) = [x for x in result.output.splitlines() if x.startswith("error:")]
    assert "initial elite search" in line
    assert "position" in line  # names the limit that no design of the box meets
    assert "Traceback" not in result.output
    # found before the run folder exists: nothing to clean up, nothing half written
    assert not (tmp_path / "runs").exists() or not any((tmp_path / "runs").iterdir())


def test_a_crash_keeps_the_folder_consistent_and_surfaces(tmp_path, monkeypatch):
    from ident.cli import run as cli_run

    def crash(self, event):
        if event.phase == "optimize" and event.step >= 3:
            raise RuntimeError("boom")

    monkeypatch.setattr(cli_run._ProgressDisplay, "update", crash)
    result = _run(QUICK, "--out", tmp_path)
    assert isinstance(result.exception, RuntimeError)
    run_dir = _only_run_dir(tmp_path)
    state = json.loads((run_dir / "run.json").read_text())
    assert state["status"] == "incomplete"
    assert "crashed during the eMuPSO run 1 of 2: RuntimeError: boom" in state["message"]
    data = json.loads((run_dir / "result.json").read_text())
    assert (data["status"], data["message"]) == (state["status"], state["message"])
    assert data["initial_elites"]["x"] is not None
    result = runner.invoke(app, ["report", str(run_dir)])
    assert result.exit_code == 0, result.output
    assert "No eMuPSO run finished" in (run_dir / "report.md").read_text()


def test_no_identifiable_elite_exits_1_with_a_plain_report(tmp_path, monkeypatch):
    import ident.run.elite_identification as estimate
    from ident.errors import NotIdentifiable

    def rank_deficient(*args, **kwargs):
        raise NotIdentifiable("parameters Izz6, Ixx6 enter the torques only in a combination")

    monkeypatch.setattr(estimate, "identify_measurements", rank_deficient)
    result = _run(QUICK, "--out", tmp_path, "--no-replay")
    assert result.exit_code == 1
    assert "no elite trajectory identifies" in result.output
    # the cause on the terminal, not only in the files
    assert "error: elite 1, wls: not identifiable on this trajectory: parameters Izz6" in (
        result.stderr
    )
    run_dir = _only_run_dir(tmp_path)
    state, saved = _statuses(run_dir)
    assert state == saved == ("complete", "run complete")  # it ran; the verdict says the rest
    md = (run_dir / "report.md").read_text()
    assert "not identifiable on this trajectory: parameters Izz6, Ixx6" in md
    assert "No estimate" in md
    assert "nan" not in md.lower()
    data = json.loads((run_dir / "result.json").read_text())
    assert data["elites"][0]["estimates"] == {}


def test_a_failure_on_the_runs_own_files_exits_1_and_both_files_say_incomplete(
    tmp_path, monkeypatch
):
    """A step after result.json failing on a file of the run (it was the replay reading an
    elite CSV with NaN torques): exit 1 with the cause, not 2 (bad input); run.json and
    result.json both incomplete with the same message (result.json said 'complete')."""
    import ident.report.run_report as run_report
    from ident.errors import DataError

    def unreadable(run_dir):
        raise DataError(f"{run_dir}/elites/elite_1.csv: non-finite value in column 'tau_j1'")

    monkeypatch.setattr(run_report, "write_replay", unreadable)
    result = _run(QUICK, "--out", tmp_path)
    assert result.exit_code == 1, result.output
    assert "error: the run stopped while writing its files: " in result.stderr
    run_dir = _only_run_dir(tmp_path)
    state, saved = _statuses(run_dir)
    assert state == saved
    assert state[0] == "incomplete"
    assert "stopped while saving the results: DataError: " in state[1]
    assert (run_dir / "INCOMPLETE").is_file()


def test_noisy_quick_run_errors_within_reported_std(tmp_path):
    noisy = tmp_path / "noisy.yaml"
    text = QUICK.read_text().replace(
        "robot: ../../../configs/paper6r.yaml",
        f"robot: {QUICK.parents[3] / 'configs' / 'paper6r.yaml'}",
    )
    noisy.write_text(text.replace("torque_noise_std: 0.0", "torque_noise_std: 0.05"))
    result = _run(noisy, "--out", tmp_path / "runs", "--no-replay")
    assert result.exit_code == 0, result.output
    data = json.loads((_only_run_dir(tmp_path / "runs") / "result.json").read_text())
    for elite in data["elites"]:
        for method in ("ols", "wls"):
            est = elite["estimates"][method]
            assert est["within_3std"] >= 0.8
            assert est["max_torque_error"] > 1e-6  # the noise is really there
            assert all(s > 0 for s in est["std"])


def test_a_retry_says_the_estimates_worst_case_now_applies(capsys):
    """The retry at a wider margin is printed when it starts, with the run's worst-case time
    from its estimate (the typical one printed at the start no longer holds); without a worst
    case, the note alone."""
    from ident.cli import run as cli_run
    from ident.inputs import JobEstimate
    from ident.run.config import load_run_config
    from ident.run.results import Progress

    cfg = load_run_config(QUICK)
    estimate = JobEstimate("run", 1e8, 100.0, worst_seconds=250.0, worst_case="if retried")
    note = "no elite kept the 30 mm margin between the checked samples; optimized again."
    with cli_run._ProgressDisplay(cfg, estimate) as display:
        display.update(Progress("retry", 0, 1, payload=note))
    err = " ".join(capsys.readouterr().err.split())
    assert f"retrying: {note} The run takes up to 4.17 min in all (its estimate)." in err
    with cli_run._ProgressDisplay(cfg, JobEstimate("run", 1e8, 100.0)) as display:
        display.update(Progress("retry", 0, 1, payload=note))
    err = " ".join(capsys.readouterr().err.split())
    assert f"retrying: {note}" in err
    assert "takes up to" not in err
