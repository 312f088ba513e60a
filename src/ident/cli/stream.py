"""``ident stream CONFIG``: a robot's log replayed into the streaming payload estimator.

Validates the config (:func:`ident.identify.streaming.stream_config.load_stream_config`), loads
the robot, reads the log and checks the reporting link before anything runs; then replays the
log at its rate (``--speed``, :class:`ident.identify.streaming.replay.LogReplay`) into
:class:`ident.identify.streaming.estimator.StreamingEstimator`, printing each detected change as
soon as it is estimated, and finally writes the run folder ``<out>/<name>-<timestamp>/`` with
``stream.json`` (settings, CPU per sample, the test's figures, every change with the new payload
in the controllers' formats and its limit checks) and ``timeline.csv`` (the scheduled estimates).
Exit codes: 0 success; 2 bad input (nothing written); 130 on Ctrl-C.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from ident.cli._common import user_errors

if TYPE_CHECKING:  # annotations only: the command imports the library when it runs
    from ident.identify.payload.controller_load import LoadLimits
    from ident.identify.streaming.estimator import StreamingEstimator
    from ident.identify.streaming.replay import StreamRun
    from ident.identify.streaming.stream_config import StreamConfig

__all__ = ["register", "stream"]


def register(app: typer.Typer) -> None:
    """Add ``stream`` to the ``ident`` command line."""
    app.command("stream")(stream)


def stream(
    config: Annotated[Path, typer.Argument(help="Stream config (docs/lifetime.md).")],
    out: Annotated[Path, typer.Option(help="Parent folder of the run folders.")] = Path("runs"),
    speed: Annotated[
        float,
        typer.Option(min=0.0, help="Replay speed: 1 the log's rate, 0 as fast as possible."),
    ] = 1.0,
) -> None:
    """Track a payload along CONFIG's log and detect its changes (streaming)."""
    from ident.dynamics.chain import chain_from_model
    from ident.dynamics.parameters import parameters_from_model
    from ident.fileio import atomic_write_text
    from ident.identify.payload.payload import link_placement
    from ident.identify.streaming.estimator import StreamingEstimator
    from ident.identify.streaming.replay import LogReplay
    from ident.identify.streaming.replay import stream as run
    from ident.identify.streaming.stream_config import load_stream_config
    from ident.inputs import check_output_dir
    from ident.measure.logs import read_log
    from ident.model.selection import load_robot
    from ident.run.rundir import run_folder

    with user_errors():
        check_output_dir(out, "--out")
        cfg = load_stream_config(config)
        source = str(cfg.source or config)
        robot = load_robot(cfg.robot, source=source)
        model = robot.model
        link, placement = link_placement(model, cfg.stream.link, source)
        terms = cfg.model.extra_terms(model.nv, source)
        joints = [str(model.names[i]) for i in range(1, model.njoints)]
        log = read_log(cfg.log, cfg.transmission, joints, source=source)
        estimator = StreamingEstimator(
            chain_from_model(model), terms, parameters_from_model(model), log.sampling_rate_hz,
            cfg.stream.settings(), placement=placement, link=link,
        )  # fmt: skip
        limits = cfg.stream.controller.limits()
        result = run(LogReplay(log, speed=speed), estimator,
                     on_event=lambda e: _print_event(e.summary(limits), link))  # fmt: skip
        summary = _summary(cfg, estimator, result, limits, link)
        with run_folder(out, cfg.name, info={"command": "stream", "config": str(config)}) as rd:
            atomic_write_text(rd.path / "stream.json", json.dumps(summary, indent=2) + "\n")
            atomic_write_text(rd.path / "timeline.csv", _timeline_csv(estimator))
            rd.finish("complete", f"{len(result.events)} change(s)")
        typer.echo(f"run folder: {rd.path}")
        typer.echo(
            f"{result.n_samples} samples, {result.cpu_per_sample_us:.1f} µs CPU per sample; "
            f"{estimator.n_tests} tests at {cfg.stream.false_alarm_per_hour:g} false alarms/h "
            f"(model-error factor kappa {estimator.kappa:.2f}); {len(result.events)} change(s)"
        )
        if estimator.timeline:
            last = estimator.timeline[-1]
            lo, hi = last.mass_interval()
            typer.echo(f"last estimate ({last.method.upper()}, t = {last.t:.1f} s): mass "
                       f"{last.mass:.4g} kg [{lo:.4g}, {hi:.4g}]")  # fmt: skip


def _print_event(event: dict, link: str) -> None:
    """One change on the terminal: what, when, the new payload, the controllers' lines."""
    a = event["after"]
    lo, hi = a["mass_interval_kg"]
    com = ", ".join(f"{1e3 * c:.1f} [{1e3 * i[0]:.1f}, {1e3 * i[1]:.1f}]"
                    for c, i in zip(a["com_m"], a["com_interval_m"], strict=True))  # fmt: skip
    typer.echo(
        f"change ({event['kind']}) at t = {event['t_onset_s']:.2f} s, detected at "
        f"{event['t_alarm_s']:.2f} s (statistic {event['statistic']:.4g} > "
        f"{event['threshold']:.4g})"
    )
    typer.echo(f"  new mass {a['mass_kg']:.4g} kg [{lo:.4g}, {hi:.4g}] (95 %), centre of mass "
               f"in {link} [mm]: {com}")  # fmt: skip
    typer.echo(f"  UR: {event['controllers']['ur']['set_target_payload']}")
    typer.echo(f"  Franka: {event['controllers']['franka']['cpp']}")
    for check in event["limit_checks"]:
        typer.echo(f"  check {check['name']}: {check['status']} ({check['detail']})")


def _summary(
    cfg: StreamConfig,
    estimator: StreamingEstimator,
    result: StreamRun,
    limits: LoadLimits,
    link: str,
) -> dict:
    """``stream.json``'s content."""
    settings = cfg.stream.settings()
    return {
        "link": link,
        "settings": vars(settings),
        "samples": result.n_samples,
        "cpu_per_sample_us": result.cpu_per_sample_us,
        "tests": estimator.n_tests,
        "false_alarm_per_hour_stated": settings.false_alarm_per_hour,
        "per_test_false_alarm_probability": estimator.alpha,
        "model_error_factor_kappa": estimator.kappa,
        "largest_statistic_over_threshold_without_alarm": estimator.max_ratio,
        "filter_delay_s": estimator.filter.delay / estimator.rate_hz,
        "changes": [e.summary(limits) for e in result.events],
        "last_estimate": estimator.timeline[-1].summary() if estimator.timeline else None,
    }


def _timeline_csv(estimator: StreamingEstimator) -> str:
    """The scheduled estimates: time, method, mass and its interval, centre of mass."""
    lines = ["t_s,method,mass_kg,mass_lo_kg,mass_hi_kg,com_x_m,com_y_m,com_z_m,effective_rows"]
    for e in estimator.timeline:
        lo, hi = e.mass_interval()
        com = ",".join(f"{c:.6g}" for c in e.com)
        lines.append(f"{e.t:.4f},{e.method},{e.mass:.6g},{lo:.6g},{hi:.6g},{com},{e.n_eff:.1f}")
    return "\n".join(lines) + "\n"
