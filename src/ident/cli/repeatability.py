"""``ident repeatability CONFIG CONFIG...``: do several logs of one robot agree?

Identifies each config's log exactly as ``ident identify`` does (nothing is written) and prints,
per base parameter, the spread of the estimates across the logs beside their predicted standard
deviation (the default interval method, :mod:`ident.identify.estimation.uncertainty`), and which
parameters disagree (:func:`ident.identify.assessment.repeatability.repeatability`: a drifting
robot, a bad log). Exit 0 when they agree, 1 when some disagree, 2 for bad input.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from ident.cli._common import user_errors

__all__ = ["register", "repeatability"]


def register(app: typer.Typer) -> None:
    """Add ``repeatability`` to the ``ident`` command line."""
    app.command("repeatability")(repeatability)


def repeatability(
    configs: Annotated[
        list[Path], typer.Argument(help="Identify configs of logs of the same robot (>= 2).")
    ],
) -> None:
    """Spread of the estimates of several logs of one robot beside their predicted std."""
    import numpy as np

    from ident.errors import IdentError
    from ident.identify.assessment.repeatability import repeatability as compare
    from ident.identify.config import load_identify_config
    from ident.identify.pipeline.real import identify

    with user_errors():
        if len(configs) < 2:
            raise IdentError("repeatability needs at least two identify configs.")
        cfgs = [load_identify_config(c) for c in configs]  # every config valid before work
        xs, stds, names = [], [], None
        for path, cfg in zip(configs, cfgs, strict=True):
            result = identify(cfg)
            unc = result.uncertainty
            if unc is None:
                raise IdentError(f"{path}: the log is too short for intervals.")
            if names is not None and unc.names != names:
                raise IdentError(
                    f"{path}: its base parameters differ from {configs[0]}'s (another robot "
                    "or model section); compare logs identified with the same model."
                )
            names = unc.names
            xs.append(result.estimate.x)
            stds.append(unc.std())
            typer.echo(f"{path}: {len(unc.names)} base parameters ({unc.method} std)")
        assert names is not None
        rep = compare(np.array(xs), np.array(stds), names)
    typer.echo("parameter | mean | spread | predicted std | spread / predicted | p")
    for k, name in enumerate(names):
        typer.echo(
            f"{name} | {rep.mean[k]:.5g} | {rep.spread[k]:.3g} | {rep.predicted[k]:.3g} | "
            f"{rep.spread[k] / rep.predicted[k]:.2f} | {rep.p_value[k]:.2g}"
        )
    if not rep.disagree:
        typer.echo(f"the {len(configs)} logs agree within their predicted std.")
        return
    for line in rep.lines():
        typer.echo(f"disagree: {line}")
    raise typer.Exit(code=1)
