"""Replay surroundings: floor, obstacles, the moment of least clearance, path colours, and the
one traced-frame rule shared by a run's replay.html and ``ident replay RUN``.

References: the config's numbers (sizes, positions, the plane's offset) read back from the
page's meshcat commands; the closest-link marker against the independent DH product of
test_replay.py.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from test_replay import URDF, dh_flange, html_commands, make_trajectory
from typer.testing import CliRunner

from ident.cli import app
from ident.viz.environment import (
    ClearanceMark,
    ReplayEnvironment,
    run_clearance_mark,
    run_environment,
    run_traced_frame,
)
from ident.viz.replay import replay_html

QUICK = Path(__file__).parent / "data" / "run" / "quick-wrist.yaml"
OBSTACLES = (
    {"name": "table", "box": {"size": [1.0, 0.6, 0.05], "position": [0.8, 0.0, 0.3]}},
    {"sphere": {"radius": 0.1, "position": [0.5, 0.5, 0.8]}},
    {"name": "wall", "plane": {"normal": [-2.0, 0.0, 0.0], "offset": -2.4}},
)


def _objects(commands: list[dict]) -> dict[str, dict]:
    return {c["path"]: c["object"] for c in commands if c["type"] == "set_object"}


def _positions(commands: list[dict]) -> dict[str, np.ndarray]:
    return {
        c["path"]: np.array(c["matrix"]).reshape(4, 4).T
        for c in commands
        if c["type"] == "set_transform"
    }


def _luminance(color: int) -> float:
    r, g, b = ((color >> s) & 0xFF for s in (16, 8, 0))
    return (0.2126 * r + 0.7152 * g + 0.0722 * b) / 255.0


def test_floor_obstacles_and_closest_marker_are_drawn():
    traj = make_trajectory()
    when = float(traj.t[37])
    page = replay_html(
        URDF,
        [traj],
        environment=ReplayEnvironment(floor_z=0.1, obstacles=OBSTACLES),
        marks=[ClearanceMark(when, "floor|flange", 0.0123)],
        title="least clearance test",
    )
    commands = html_commands(page)
    objects, poses = _objects(commands), _positions(commands)
    root = "/meshcat/replay/robot_0/environment"
    # floor: a semi-opaque slab whose top is just under z = 0.1
    floor = objects["/meshcat/replay/floor"]
    assert floor["geometries"][0]["type"] == "BoxGeometry"
    assert floor["materials"][0]["transparent"]
    assert 0.0 < floor["materials"][0]["opacity"] < 1.0
    top = poses["/meshcat/replay/floor"][2, 3] + floor["geometries"][0]["depth"] / 2
    assert top == pytest.approx(0.1, abs=2e-3)
    # box: size and centre of the config
    box = objects[f"{root}/table"]["geometries"][0]
    assert (box["width"], box["height"], box["depth"]) == pytest.approx((1.0, 0.6, 0.05))
    np.testing.assert_allclose(poses[f"{root}/table"][:3, 3], [0.8, 0.0, 0.3])
    sphere = objects[f"{root}/obstacle_1"]["geometries"][0]
    assert sphere["type"] == "SphereGeometry"
    assert sphere["radius"] == pytest.approx(0.1)
    np.testing.assert_allclose(poses[f"{root}/obstacle_1"][:3, 3], [0.5, 0.5, 0.8])
    # plane -2 x <= -2.4, i.e. x >= 1.2 solid: a slab on x = 1.2, its thin axis along x
    wall = poses[f"{root}/wall"]
    np.testing.assert_allclose(abs(wall[:3, 2] @ [1.0, 0.0, 0.0]), 1.0, atol=1e-12)
    assert wall[0, 3] == pytest.approx(1.2, abs=5e-3)
    assert wall[0, 3] > 1.2  # on the solid side
    # the closest link (the flange) at the time of least clearance, by the DH product
    marker = poses["/meshcat/replay/robot_0/closest"][:3, 3]
    np.testing.assert_allclose(marker, dh_flange(traj.q[37]), atol=1e-9)
    assert "smallest clearance 12.3 mm (floor|flange)" in page
    assert "<title>least clearance test</title>" in page


def test_default_floor_and_dark_path_colours():
    commands = html_commands(
        replay_html(URDF, [make_trajectory(phase=p) for p in (0.0, 1.0, 2.0, 3.0, 4.0, 5.0)])
    )
    assert "/meshcat/replay/floor" in _objects(commands)  # z = 0 by default
    lines = [
        o["materials"][0]["color"] for p, o in _objects(commands).items() if p.endswith("/path")
    ]
    assert len(lines) == 6
    for color in lines:  # readable on meshcat's light sky and the grey floor: no white/yellow
        assert color != 0xFFFFFF
        assert _luminance(color) < 0.5


def test_no_floor_when_disabled():
    env = run_environment({"config": {"safety": {"floor": {"enabled": False, "z": 0.0}}}})
    assert env.floor_z is None
    commands = html_commands(replay_html(URDF, [make_trajectory()], environment=env))
    assert "/meshcat/replay/floor" not in _objects(commands)


def test_run_traced_frame_rule():
    assert run_traced_frame({"excitation": {"traced_frame": "flange"}}) == "flange"
    assert run_traced_frame({"traced_frame": "tool0", "excitation": {}}) == "tool0"
    assert run_traced_frame({"excitation": {}, "config": {"stage": "arm"}}) == "wrist_centre"
    assert run_traced_frame({"excitation": {}, "config": {"stage": "wrist"}}) is None
    assert run_traced_frame({}) is None


@pytest.mark.slow
def test_run_replay_and_cli_replay_show_the_same_scene(tmp_path):
    out = tmp_path / "runs"
    result = CliRunner().invoke(app, ["run", str(QUICK), "--out", str(out), "--no-replay"])
    assert result.exit_code == 0, result.output
    (run,) = list(out.iterdir())
    # an arm-stage result with obstacles: the wrist centre is traced by both
    data = json.loads((run / "result.json").read_text())
    data["config"]["stage"] = "arm"
    data["config"]["safety"] = {"floor": {"enabled": True, "z": -0.05}, "obstacles": OBSTACLES}
    (run / "result.json").write_text(json.dumps(data))
    from ident.report.run_data import write_replay

    assert write_replay(run) == "replay.html written (traced frame: wrist_centre)."
    mark = run_clearance_mark(data, data["chosen_elite"])
    assert mark is not None
    page = (run / "replay.html").read_text()
    assert mark.describe() in page  # title and caption
    cli_html = tmp_path / "cli.html"
    elite = run / "elites" / f"elite_{data['chosen_elite']}.csv"
    result = CliRunner().invoke(
        app, ["replay", str(run), "--trajectory", str(elite), "--html", str(cli_html)]
    )
    assert result.exit_code == 0, result.output
    assert "traced frame wrist_centre" in result.output
    run_cmds, cli_cmds = html_commands(page), html_commands(cli_html.read_text())
    for path in (
        "/meshcat/replay/floor",
        "/meshcat/replay/robot_0/environment/table",
        "/meshcat/replay/robot_0/environment/wall",
        "/meshcat/replay/robot_0/closest",
    ):
        assert path in _objects(run_cmds)
        assert path in _objects(cli_cmds)
    np.testing.assert_allclose(
        _positions(run_cmds)["/meshcat/replay/robot_0/closest"],
        _positions(cli_cmds)["/meshcat/replay/robot_0/closest"],
    )
    run_path = _objects(run_cmds)["/meshcat/replay/robot_0/path"]
    cli_path = _objects(cli_cmds)["/meshcat/replay/robot_0/path"]
    assert run_path["geometries"][0]["data"] == cli_path["geometries"][0]["data"]
