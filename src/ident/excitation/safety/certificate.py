"""The exact clearances of a safety model's checked pairs: what the dense check certifies.

Meshes are measured as they are (coal BVH), primitives as primitives; the convex hulls (a
lower bound: a hull contains its mesh) stand in only where a caller says the exact value is
not needed (:func:`_clearances` with ``within``). :func:`_poor_hull_pairs` times one posture
of the dense check and finds the mesh pairs whose hulls are too poor a proxy for the cheap
term, when the model is built.
"""

from __future__ import annotations

import bisect
import time
from collections.abc import Sequence

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ident.excitation.family import FloatArray
from ident.excitation.safety.distances import (
    CheckedPairs,
    _distances,
    _exact_into,
    _geometry_data,
)

__all__: list[str] = []  # the package's own steps, imported by name


def _clearances(
    checked: CheckedPairs,
    q: npt.ArrayLike,
    within: npt.ArrayLike | None = None,
    travel: npt.ArrayLike | None = None,
) -> FloatArray:
    """:meth:`ident.excitation.safety.SafetyModel.clearances` of the ``checked`` pairs [m],
    shape (n_samples, n_pairs)."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    out = np.full((q.shape[0], checked.n_pairs), np.inf)
    if checked.n_pairs == 0:
        return out
    finite = np.all(np.isfinite(q), axis=1)
    q = np.where(finite[:, None], q, 0.0)
    distances = _distances(checked.model, checked.hulls, q)
    mesh = checked.mesh
    if mesh.any():
        gdata = _geometry_data(checked.exact)
        if within is None:
            for s in range(q.shape[0]):
                _exact_into(checked, q[s], np.flatnonzero(mesh).tolist(), gdata, distances[s])
        else:
            limit = np.asarray(within, dtype=float)[:, checked.group]
            need = mesh[None, :] & (distances < limit)
            moved = None if travel is None else np.asarray(travel, dtype=float)[:, checked.group]
            exact = _exact_needed(checked, q, distances, need, limit, moved, gdata)
            _exact_smallest(checked, q, distances, exact, moved, gdata)
    out = checked.pair_minimum(distances)
    out[~finite] = -np.inf
    return out


def _exact_needed(
    checked: CheckedPairs,
    q: FloatArray,
    distances: FloatArray,
    need: npt.NDArray[np.bool_],
    limit: FloatArray,
    travel: FloatArray | None,
    gdata: pin.GeometryData,
) -> npt.NDArray[np.bool_]:
    """Where ``need`` (n_samples, n_geometry_pairs) marks a hull distance below ``limit`` [m],
    a value of ``distances`` [m] that is exact or at least ``limit``, in place; returns where
    the values are exact.

    Without ``travel`` every needed value is measured. With it (a nondecreasing bound of each
    pair's relative motion from the first sample [m], same shape), conservative advancement:
    a distance changes no faster than its bodies move, so a pair measured ``e`` at sample
    ``r`` is at least ``e - (travel[s] - travel[r])`` at a later sample ``s``; where that
    bound keeps ``limit`` the sample is skipped and the bound (a better lower bound than the
    hulls') stands in.
    """
    if travel is None:
        for s in np.flatnonzero(need.any(axis=1)):
            _exact_into(checked, q[s], np.flatnonzero(need[s]).tolist(), gdata, distances[s])
        return need
    exact = np.zeros_like(need)
    last = np.full(need.shape[1], -np.inf)  # each pair's last exact distance [m]
    since = np.zeros(need.shape[1])  # the travel at that sample [m]
    for s in np.flatnonzero(need.any(axis=1)):
        bound = last - (travel[s] - since)
        skip = need[s] & (bound >= limit[s])
        distances[s, skip] = np.maximum(distances[s, skip], bound[skip])
        measured = np.flatnonzero(need[s] & ~skip)
        if measured.size:
            _exact_into(checked, q[s], measured.tolist(), gdata, distances[s])
            last[measured] = distances[s, measured]
            since[measured] = travel[s, measured]
            exact[s, measured] = True
    return exact


def _exact_smallest(
    checked: CheckedPairs,
    q: FloatArray,
    distances: FloatArray,
    exact: npt.NDArray[np.bool_],
    travel: FloatArray | None,
    gdata: pin.GeometryData,
) -> None:
    """Make each mesh pair's smallest value of ``distances`` (n_samples, n_geometry_pairs)
    [m] exact, in place: ``exact`` marks the values already exact, the others are lower
    bounds, visited in increasing order and measured until one is not below the smallest
    exact distance found.

    With ``travel`` (see :func:`_exact_needed`) a value is also skipped when its bound from
    the nearest exact samples before and after it, less the travel between (a distance
    changes no faster than its bodies move), is not below the smallest found; at the end the
    unmeasured values are raised to those bounds (:func:`_lower_bounds`; still lower bounds),
    so that none is below the exact smallest.
    """
    for p in np.flatnonzero(checked.mesh).tolist():
        column = distances[:, p]  # a view: _exact_into writes through it
        known = exact[:, p].copy()
        moved = None if travel is None else travel[:, p]
        measured = np.flatnonzero(known).tolist()  # sorted
        best = column[known].min() if known.any() else np.inf
        rest = np.flatnonzero(~known)
        for s in rest[np.argsort(column[rest], kind="stable")].tolist():
            if column[s] >= best:  # values in increasing order: done
                break
            i = bisect.bisect(measured, s)
            if moved is not None and _bounded_by_neighbours(column, moved, measured, i, s, best):
                continue
            _exact_into(checked, q[s], [p], gdata, distances[s])
            measured.insert(i, s)
            known[s] = True
            best = min(best, column[s])
        if moved is not None:
            lower = _lower_bounds(column, known, moved)
            column[~known] = lower[~known]


def _bounded_by_neighbours(
    column: FloatArray, travel: FloatArray, measured: list[int], i: int, s: int, best: float
) -> bool:
    """Whether the exact value before sample ``s`` (``measured[i - 1]``) or after it
    (``measured[i]``), less the ``travel`` [m] between, keeps ``best`` [m] at ``s``."""
    if i > 0 and column[measured[i - 1]] - (travel[s] - travel[measured[i - 1]]) >= best:
        return True
    return i < len(measured) and column[measured[i]] - (travel[measured[i]] - travel[s]) >= best


def _lower_bounds(
    column: FloatArray, known: npt.NDArray[np.bool_], travel: FloatArray
) -> FloatArray:
    """Lower bounds of one pair's distances (n_samples,) [m] at the samples not ``known``
    (``inf`` at the known ones): the value itself, and the nearest exact values before and
    after less the ``travel`` [m] between (a distance changes no faster than its bodies
    move)."""
    if not known.any():
        return np.where(known, np.inf, column)
    measured = np.flatnonzero(known)
    samples = np.arange(column.size)
    # a sample before the first (after the last) exact one takes that one's bound twice
    before = measured[np.maximum(np.searchsorted(measured, samples, "right") - 1, 0)]
    after = measured[np.minimum(np.searchsorted(measured, samples), measured.size - 1)]
    from_before = column[before] - np.abs(travel - travel[before])
    from_after = column[after] - np.abs(travel[after] - travel)
    lower = np.maximum(column, np.maximum(from_before, from_after))
    return np.where(known, np.inf, lower)


def _pair_clearances(checked: CheckedPairs, q: npt.ArrayLike, columns: Sequence[int]) -> FloatArray:
    """:meth:`ident.excitation.safety.SafetyModel.pair_clearances` of the ``checked`` pairs
    [m], shape (n_samples, len(columns))."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    columns = [int(c) for c in columns]
    out = np.full((q.shape[0], len(columns)), np.inf)
    where = {c: i for i, c in enumerate(columns)}
    group = checked.group
    pairs = [p for p in range(group.size) if int(group[p]) in where]
    model, geom = checked.model, checked.exact
    data, gdata = model.createData(), _geometry_data(geom)
    for s in range(q.shape[0]):
        if not np.all(np.isfinite(q[s])):
            out[s] = -np.inf
            continue
        pin.updateGeometryPlacements(model, data, geom, gdata, q[s])
        for p in pairs:
            d = pin.computeDistance(geom, gdata, p).min_distance
            i = where[int(group[p])]
            out[s, i] = min(out[s, i], d)
    return out


def _poor_hull_pairs(
    checked: CheckedPairs, postures: FloatArray, clearance_m: float
) -> tuple[npt.NDArray[np.bool_], float, float, float]:
    """Mesh pairs whose hulls are closer than the margin ``clearance_m`` [m] in at least half
    of 100 sampled ``postures``: the cheap term measures them on the meshes (a hull would
    forbid too much). Also returns the model's ``seconds_per_posture`` (the CPU of one
    posture of the dense check, :func:`_exact_cost` included), ``hull_seconds_per_posture``
    (the hulls' alone) and ``mesh_seconds_per_posture`` (every mesh pair's exact distance at
    one posture) [s]."""
    poor = np.zeros(checked.mesh.shape, dtype=bool)
    n = 101 if checked.mesh.any() and clearance_m > 0.0 else 11
    start = time.process_time()
    hull = _distances(checked.model, checked.hulls, postures[:n])
    seconds_per_posture = (time.process_time() - start) / n
    hull_seconds_per_posture = seconds_per_posture
    if n == 11:
        return poor, seconds_per_posture, hull_seconds_per_posture, 0.0
    near, mesh_seconds = _exact_cost(checked, postures, clearance_m, hull)
    seconds_per_posture += near
    poor = checked.mesh & (np.mean(hull < clearance_m, axis=0) >= 0.5)
    return poor, seconds_per_posture, hull_seconds_per_posture, mesh_seconds


def _exact_cost(
    checked: CheckedPairs, postures: FloatArray, clearance_m: float, hull: FloatArray
) -> tuple[float, float]:
    """The meshes' CPU of one posture of the dense check [s], to add to the hulls' and
    primitives' (timed): from ``hull``, the hulls' distances at sampled ``postures``
    (n, n_geometry_pairs) [m], each mesh pair's exact distance (timed here on one posture)
    where its hulls are within the margin and 1 mm (where the dense check,
    :func:`_clearances` with ``within``, measures the mesh). Also the CPU of every mesh
    pair's exact distance at that posture [s]: the dense check makes each pair's smallest
    value exact (:func:`_exact_smallest`), wherever it is, which costs a share of that."""
    mesh = np.flatnonzero(checked.mesh)
    share = np.mean(hull[:, mesh] < clearance_m + 1e-3, axis=0)
    needed = mesh[share > 0.0]
    gdata = _geometry_data(checked.exact)
    row = np.zeros(hull.shape[1])
    start = time.process_time()
    _exact_into(checked, postures[1], needed.tolist(), gdata, row)
    near = time.process_time() - start
    _exact_into(checked, postures[1], mesh[share == 0.0].tolist(), gdata, row)
    every = time.process_time() - start
    if not needed.size:
        return 0.0, every
    return near / needed.size * float(share.sum()), every
