"""``ident replay``: watch a trajectory in meshcat, live on 127.0.0.1 or as a static HTML file."""

from __future__ import annotations

import json
import re
import time
import webbrowser
from pathlib import Path
from typing import Annotated

import typer

from ident.cli._common import one_line, user_errors
from ident.errors import DataError

# Bounds of a replay: the animation holds one keyframe per 1/fps s of replay time for every
# robot, and the page (or the browser) holds all of them.
MIN_SPEED, MAX_SPEED = 1e-3, 1e3
MAX_KEYFRAMES = 200_000  # about 1.9 h of replay at 30 keyframes per second
_MAX_TRAJECTORY_BYTES = 500 << 20

__all__ = ["register", "replay"]


def _elite_csvs(run_dir: Path) -> list[Path]:
    """``elites/elite_<k>.csv`` of a run folder, by rank ``k`` (path files excluded)."""
    found = []
    for path in (run_dir / "elites").glob("elite_*.csv"):
        match = re.fullmatch(r"elite_(\d+)\.csv", path.name)
        if match:
            found.append((int(match.group(1)), path))
    return [p for _, p in sorted(found)]


def _result_of_run(run_dir: Path) -> dict:
    """The run's ``result.json`` (``{}`` when it has none)."""
    path = run_dir / "result.json"
    if not path.is_file():
        return {}
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError, RecursionError) as e:
        raise DataError(
            f"{path}: not valid JSON ({one_line(e)[:200]}); pass --frame to choose the frame."
        ) from e
    if not isinstance(data, dict):
        raise DataError(
            f"{path}: expected a JSON object, got {type(data).__name__}; the run folder is "
            "damaged, pass --frame to choose the frame."
        )
    return data


def _inputs(
    run_dir: Path | None, urdf: Path | None, trajectory: Path | None, elites: bool
) -> tuple[Path, list[Path], dict]:
    """Resolve the URDF, the trajectory CSVs and the run's ``result.json`` (or ``{}``)."""
    if run_dir is None:
        if urdf is None or trajectory is None:
            raise DataError(
                "give a run folder (ident replay runs/<name>) or both --urdf and --trajectory."
            )
        return urdf, [trajectory], {}
    if not run_dir.is_dir():
        raise DataError(f"{run_dir}: run folder not found.")
    urdf = urdf or run_dir / "robot.urdf"
    if not urdf.is_file():
        raise DataError(f"{run_dir}: no robot.urdf in the run folder; pass --urdf PATH.")
    chosen = trajectory or run_dir / "trajectory.csv"
    if not chosen.is_file():
        raise DataError(
            f"{run_dir}: no trajectory.csv in the run folder (the run did not finish its "
            "excitation stage?); pass --trajectory CSV."
        )
    csvs = [chosen]
    if elites:
        others = _elite_csvs(run_dir)
        if not others:
            raise DataError(f"{run_dir}: --elites given but no elites/elite_<k>.csv found.")
        # The chosen trajectory is usually also an elite: show each motion once.
        csvs += [p for p in others if p.read_bytes() != chosen.read_bytes()]
    return urdf, csvs, _result_of_run(run_dir)


def _elite_rank(path: Path) -> int | None:
    """``k`` of ``elite_<k>.csv``, else None."""
    match = re.fullmatch(r"elite_(\d+)\.csv", path.name)
    return int(match.group(1)) if match else None


def replay(
    run_dir: Annotated[
        Path | None,
        typer.Argument(help="Run folder of `ident run` (robot.urdf, trajectory.csv, elites/)."),
    ] = None,
    urdf: Annotated[Path | None, typer.Option(help="Robot URDF (overrides the run's).")] = None,
    trajectory: Annotated[
        Path | None,
        typer.Option(help="Trajectory CSV: t, q_<joint>...[, dq_..., ddq_..., tau_...]"),
    ] = None,
    frame: Annotated[
        str | None,
        typer.Option(help="Frame whose path is drawn (default: the run's, else flange/tool0)."),
    ] = None,
    speed: Annotated[float, typer.Option(help="Replay speed factor (1 = true speed).")] = 1.0,
    loop: Annotated[bool, typer.Option(help="Repeat the motion.")] = True,
    elites: Annotated[
        bool, typer.Option(help="Also show the run's other elites, side by side along y.")
    ] = False,
    html: Annotated[
        Path | None,
        typer.Option(help="Write a self-contained HTML file instead of starting a server."),
    ] = None,
    port: Annotated[
        int, typer.Option(help="First web port to try (the next free one is taken).")
    ] = 7000,
    open_browser: Annotated[
        bool, typer.Option("--open", help="Open the viewer in the system's web browser.")
    ] = False,
    package_dir: Annotated[
        list[Path] | None,
        typer.Option(help="Folder holding package:// mesh packages (repeatable)."),
    ] = None,
) -> None:
    """Replay the excitation motion of RUN_DIR (or --urdf/--trajectory) in meshcat.

    Without --html, serves the viewer on http://127.0.0.1:<port>/static/ until Ctrl-C.
    """
    with user_errors():
        from ident.config import read_text_input
        from ident.fileio import atomic_write_text
        from ident.inputs import check_number, check_output_file, read_urdf_text
        from ident.trajectory import read_trajectory_csv
        from ident.viz.environment import (
            ReplayEnvironment,
            run_clearance_mark,
            run_environment,
            run_traced_frame,
        )
        from ident.viz.replay import DEFAULT_FPS, build_replay_scene
        from ident.viz.server import LoopbackMeshcatServer

        check_number(speed, "--speed", low=MIN_SPEED, high=MAX_SPEED, hint="(1 = true speed)")
        if html is None:
            check_number(port, "--port", low=0, high=65535, integer=True, hint="(0: any free)")
        else:
            check_output_file(html, "--html")
        for folder in package_dir or ():
            if not folder.is_dir():
                raise DataError(
                    f"--package-dir {folder}: not a folder; give the folder that holds the "
                    "package:// mesh packages (e.g. the parent of <package>/meshes)."
                )
        urdf_path, csvs, run_data = _inputs(run_dir, urdf, trajectory, elites)
        run_frame = run_traced_frame(run_data)
        # the run's floor and obstacles (a floor at z = 0 without a run); the least
        # clearance of an elite's own file (trajectory.csv has its own time axis)
        try:
            environment = run_environment(run_data) if run_data else ReplayEnvironment()
            ranks = [_elite_rank(p) for p in csvs]
            marks = [None if r is None else run_clearance_mark(run_data, r) for r in ranks]
        except DataError as e:
            raise DataError(f"{run_dir}/{e}") from None
        read_urdf_text(urdf_path)
        for p in csvs:  # one clear line for a binary, non-UTF-8 or huge file
            read_text_input(p, what="trajectory", max_bytes=_MAX_TRAJECTORY_BYTES)
        # positions suffice to replay: a log t, q_* is read too (dq, ddq derived, unused)
        trajectories = [read_trajectory_csv(p, allow_positions_only=True) for p in csvs]
        for p, traj in zip(csvs, trajectories, strict=True):
            span = float(traj.t[-1] - traj.t[0])
            if span / speed * DEFAULT_FPS > MAX_KEYFRAMES:
                raise DataError(
                    f"{p}: {span:.3g} s at --speed {speed:g} is "
                    f"{span / speed / 3600:.3g} h of replay, more than the "
                    f"{MAX_KEYFRAMES / DEFAULT_FPS / 3600:.2g} h a replay holds; raise --speed "
                    "or cut the trajectory."
                )
        scene = build_replay_scene(
            urdf_path,
            trajectories,
            traced_frame=frame or run_frame,
            speed=speed,
            loop=loop,
            package_dirs=package_dir or (),
            labels=[p.name for p in csvs],
            environment=environment,
            marks=marks,
        )
        what = f"{len(trajectories)} trajectory(ies), {scene.duration:.2f} s at speed {speed:g}"
        if html is not None:
            page = scene.recorder.static_html(
                f"ident replay: {urdf_path.stem}", scene.caption_html()
            )
            atomic_write_text(html, page)
            typer.echo(f"wrote {html} ({what}; traced frame {scene.traced_frame})")
            return
        with LoopbackMeshcatServer(port=port) as server:
            server.push(scene.recorder)
            typer.echo(f"replaying {what}; traced frame {scene.traced_frame}")
            for k, (label, color) in enumerate(zip(scene.labels, scene.colors, strict=True)):
                typer.echo(f"  robot {k} (path #{color:06x}): {label}")
            typer.echo(f"open {server.web_url}  (Ctrl-C to stop)")
            if open_browser and not webbrowser.open(server.web_url, new=2):
                typer.echo("no system browser found: open the URL above yourself", err=True)
            # SIGTERM (kill, systemd) stops the server like Ctrl-C does (user_errors).
            while True:  # the server runs in a daemon thread; Ctrl-C ends this loop
                time.sleep(0.5)


def register(app: typer.Typer) -> None:
    """Add ``ident replay`` to the application."""
    app.command(name="replay")(replay)
