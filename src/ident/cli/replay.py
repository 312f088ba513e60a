"""``ident replay``: watch a trajectory in meshcat, live on 127.0.0.1 or as a static HTML file."""

from __future__ import annotations

import json
import re
import time
import warnings
import webbrowser
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, NamedTuple

import typer

from ident.cli._common import PackageDirOption, check_package_dirs, one_line, user_errors
from ident.errors import DataError, IdentError, IdentWarning

if TYPE_CHECKING:  # imported when the command runs: the CLI starts fast
    from ident.model.selection import RobotSelection
    from ident.trajectory import JointTrajectory
    from ident.viz.environment import ClearanceMark, ReplayEnvironment
    from ident.viz.replay import ReplayScene

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


def _run_robot(run_dir: Path, run_data: dict) -> dict | None:
    """The run's ``robot`` config section (resolved paths), or None.

    ``ident run`` keeps it in ``result.json`` (``config.robot``); ``ident identify`` names its
    config in ``run.json``, read again if it is still there.
    """
    config = run_data.get("config")
    if isinstance(config, dict) and isinstance(config.get("robot"), dict):
        return config["robot"]
    try:
        info = json.loads((run_dir / "run.json").read_text(encoding="utf-8"))
        path = Path(info["config"]) if info.get("command") == "identify" else None
    except (OSError, ValueError, KeyError, TypeError, RecursionError):
        return None
    if path is None:
        return None
    if not path.is_file():  # relative to where ident ran: runs/<name> -> its parent's parent
        path = run_dir.resolve().parent.parent / path
        if not path.is_file():
            return None
    from ident.identify.config import load_identify_config

    try:
        return load_identify_config(path).robot.model_dump()
    except IdentError:
        return None


def _elite_rank(path: Path) -> int | None:
    """``k`` of ``elite_<k>.csv``, else None."""
    match = re.fullmatch(r"elite_(\d+)\.csv", path.name)
    return int(match.group(1)) if match else None


# The options that select the robot's chain and its meshes (their help is the command's
# --help).
_LockOption = Annotated[
    list[str] | None,
    typer.Option(
        "--lock",
        help="Hold joint NAME fixed at VALUE [rad or m] (0 if omitted), e.g. the fingers "
        "of a gripper; repeatable. Replaces the run's chain selection.",
        metavar="NAME[=VALUE]",
    ),
]
_BaseLinkOption = Annotated[
    str | None, typer.Option("--base-link", help="First link of the chain.")
]
_TipLinkOption = Annotated[str | None, typer.Option("--tip-link", help="Last link of the chain.")]
_ForceOption = Annotated[bool, typer.Option("--force", help="Replace an existing --html file.")]


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
    force: _ForceOption = False,
    package_dir: PackageDirOption = None,
    lock: _LockOption = None,
    base_link: _BaseLinkOption = None,
    tip_link: _TipLinkOption = None,
) -> None:
    """Replay the excitation motion of RUN_DIR (or --urdf/--trajectory) in meshcat.

    The trajectory moves the chain's joints; the URDF's other joints are held at their
    --lock values (a run folder: the run's robot.lock, base_link and tip_link, unless one of
    these flags is given). Without --html, serves the viewer on
    http://127.0.0.1:<port>/static/ until Ctrl-C.
    """
    with user_errors():
        from ident.cli.verify import parse_locks

        _check_options(speed, html, port, package_dir or [], force)
        locks = parse_locks(lock or [])
        urdf_path, csvs, run_data = _inputs(run_dir, urdf, trajectory, elites)
        selection = _robot_selection(
            run_dir, run_data, urdf, urdf_path, locks, base_link, tip_link, package_dir or []
        )
        context = _run_context(run_dir, run_data, csvs)
        trajectories = _read_trajectories(urdf_path, csvs, speed)
        scene = _record_scene(selection, trajectories, csvs, context, frame, speed, loop)
        what = f"{len(trajectories)} trajectory(ies), {scene.duration:.2f} s at speed {speed:g}"
        if html is not None:
            _write_page(html, scene, urdf_path, what)
        else:
            _serve(scene, port, open_browser, what)


def _check_options(
    speed: float, html: Path | None, port: int, package_dirs: list[Path], force: bool
) -> None:
    """Check --speed, --port (served) or --html (written; an existing file only with
    ``force``), and --package-dir."""
    from ident.inputs import check_number, check_output_file

    check_number(speed, "--speed", low=MIN_SPEED, high=MAX_SPEED, hint="(1 = true speed)")
    if html is None:
        check_number(port, "--port", low=0, high=65535, integer=True, hint="(0: any free)")
    else:
        check_output_file(html, "--html", force_flag=None if force else "--force")
    check_package_dirs(package_dirs)


def _robot_selection(
    run_dir: Path | None,
    run_data: dict,
    urdf: Path | None,
    urdf_path: Path,
    locks: dict[str, float],
    base_link: str | None,
    tip_link: str | None,
    package_dirs: list[Path],
) -> RobotSelection:
    """The replayed robot: a run folder's own chain (its locked joints, their values and its
    mesh folders) when neither --urdf, --lock, --base-link nor --tip-link is given; else the
    chain these flags select on ``urdf_path``."""
    from ident.model.selection import selection_from_flags
    from ident.viz.replay import run_robot_selection

    if run_dir is not None and urdf is None and not (locks or base_link or tip_link):
        return run_robot_selection(run_dir, _run_robot(run_dir, run_data), package_dirs)
    return selection_from_flags(
        urdf=urdf_path,
        lock=locks,
        base_link=base_link,
        tip_link=tip_link,
        package_dirs=list(package_dirs),
    )


class _RunContext(NamedTuple):
    """What a run folder adds to the replay (``None`` and defaults without one)."""

    traced_frame: str | None  # the run's traced frame
    environment: ReplayEnvironment  # its floor and obstacles
    marks: list[ClearanceMark | None]  # per trajectory CSV, an elite's least clearance


def _run_context(run_dir: Path | None, run_data: dict, csvs: list[Path]) -> _RunContext:
    """The run's traced frame, floor and obstacles (a floor at z = 0 without a run), and the
    least clearance of each elite's own file (trajectory.csv has its own time axis)."""
    from ident.viz.environment import (
        ReplayEnvironment,
        run_clearance_mark,
        run_environment,
        run_traced_frame,
    )

    run_frame = run_traced_frame(run_data)
    try:
        environment = run_environment(run_data) if run_data else ReplayEnvironment()
        ranks = [_elite_rank(p) for p in csvs]
        marks = [None if r is None else run_clearance_mark(run_data, r) for r in ranks]
    except DataError as e:
        raise DataError(f"{run_dir}/{e}") from None
    return _RunContext(run_frame, environment, marks)


def _read_trajectories(urdf_path: Path, csvs: list[Path], speed: float) -> list[JointTrajectory]:
    """Check the URDF is readable, then read the trajectory CSVs (positions suffice) and bound
    their replay: at most :data:`MAX_KEYFRAMES` keyframes each at ``speed``."""
    from ident.config import read_text_input
    from ident.inputs import read_urdf_text
    from ident.trajectory import read_trajectory_csv
    from ident.viz.replay import DEFAULT_FPS, replay_duration

    read_urdf_text(urdf_path)
    for p in csvs:  # one clear line for a binary, non-UTF-8 or huge file
        read_text_input(p, what="trajectory", max_bytes=_MAX_TRAJECTORY_BYTES)
    # positions suffice to replay: a log t, q_* is read too (dq, ddq derived, unused)
    trajectories = [read_trajectory_csv(p, allow_positions_only=True) for p in csvs]
    for p, traj in zip(csvs, trajectories, strict=True):
        span = replay_duration(traj.t)  # the segments' spans (gaps are skipped)
        if span / speed * DEFAULT_FPS > MAX_KEYFRAMES:
            raise DataError(
                f"{p}: {span:.3g} s at --speed {speed:g} is "
                f"{span / speed / 3600:.3g} h of replay, more than the "
                f"{MAX_KEYFRAMES / DEFAULT_FPS / 3600:.2g} h a replay holds; raise --speed "
                "or cut the trajectory."
            )
    return trajectories


def _record_scene(
    selection: RobotSelection,
    trajectories: list[JointTrajectory],
    csvs: list[Path],
    context: _RunContext,
    frame: str | None,
    speed: float,
    loop: bool,
) -> ReplayScene:
    """The replay scene, one robot per CSV (labelled by its name); ``frame`` overrides the
    run's traced frame. Mesh warnings are printed as ``warning: ...`` lines, also when the
    scene fails."""
    from ident.viz.replay import build_replay_scene

    with warnings.catch_warnings(record=True) as caught:  # e.g. meshes not found
        try:
            warnings.simplefilter("always", IdentWarning)
            return build_replay_scene(
                selection,
                trajectories,
                traced_frame=frame or context.traced_frame,
                speed=speed,
                loop=loop,
                labels=[p.name for p in csvs],
                environment=context.environment,
                marks=context.marks,
            )
        finally:  # the mesh warnings also when the replay fails
            for w in caught:
                if issubclass(w.category, IdentWarning):
                    typer.echo(f"warning: {one_line(w.message)}", err=True)
                else:
                    warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)


def _write_page(html: Path, scene: ReplayScene, urdf_path: Path, what: str) -> None:
    """Write the scene as a self-contained page (meshcat's static export) to ``html``."""
    from ident.fileio import atomic_write_text

    page = scene.recorder.static_html(f"ident replay: {urdf_path.stem}", scene.caption_html())
    atomic_write_text(html, page)
    typer.echo(f"wrote {html} ({what}; traced frame {scene.traced_frame})")


def _serve(scene: ReplayScene, port: int, open_browser: bool, what: str) -> None:
    """Serve the scene on 127.0.0.1 (``port`` or the next free one) until Ctrl-C."""
    from ident.viz.server import LoopbackMeshcatServer

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
