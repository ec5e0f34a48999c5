"""``workbench measure``: the terrain experiment's own command (declared in its
:class:`~workbench.core.experiment.Command` row; the CLI and ``workbench.measure`` find it
in the registry), measuring in a terrain run's halftone model folder."""

from __future__ import annotations

import json
from collections.abc import Iterable
from pathlib import Path

import typer

from workbench.errors import WorkbenchError


def measure(model: str | Path, points: Iterable[str] = (), lines: Iterable[str] = (),
            polygons: Iterable[str] = ()) -> list:
    """Measure in a terrain run's halftone model folder: ``points`` ``"u,v"``, ``lines``
    ``"u1,v1:u2,v2"``, ``polygons`` ``"u1,v1:u2,v2:u3,v3..."`` (image II's pixels); each a
    :class:`~workbench.experiments.terrain.products.measure.Measurement` with values and standard
    deviations. Bad input raises :class:`~workbench.errors.WorkbenchError` (one line)."""
    from workbench.experiments.terrain.products import measure as ms
    from workbench.experiments.terrain.products import model as tm

    points, lines, polygons = list(points), list(lines), list(polygons)
    if not (points or lines or polygons):
        raise WorkbenchError("nothing to measure: give --point u,v, --line u1,v1:u2,v2 or --polygon u1,v1:u2,v2:u3,v3")
    return ms.measure(tm.load(model), points, lines, polygons)


def measure_command(
        model: str = typer.Argument(..., help="A halftone model folder (a terrain run's <out>.model)."),
        point: list[str] = typer.Option([], "--point", help="u,v: image II's pixel -> ground X, Y, H and the "
                                        "terrain's slope there (repeatable)."),
        line: list[str] = typer.Option([], "--line", help="u1,v1:u2,v2 -> distance, slope distance, height "
                                       "difference, slope (repeatable)."),
        polygon: list[str] = typer.Option([], "--polygon", help="u1,v1:u2,v2:u3,v3... -> area, perimeter, mean "
                                          "height (repeatable)."),
        as_json: bool = typer.Option(False, "--json", help="Print JSON instead of lines.")) -> None:
    """Measure in a terrain run's halftone model: ground coordinates, heights, distances, slopes and
    areas, each with its standard deviation from the refined orientation's covariance."""
    found = measure(model, points=point, lines=line, polygons=polygon)
    if as_json:
        typer.echo(json.dumps([m.to_json() for m in found], indent=1))
    else:
        typer.echo("\n".join(m.text() for m in found))
