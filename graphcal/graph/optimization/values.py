"""Copying variables between ``gtsam.Values`` and across processes (Pose2 or vector: the
variables of graphcal's segment graphs)."""

from __future__ import annotations

import gtsam
import numpy as np

#: A variable's value as plain data, picklable: ``("pose2", [x, y, cos, sin])`` or
#: ``("vector", array)``.
Portable = tuple[str, np.ndarray]


def copy_value(
    target: gtsam.Values, source: gtsam.Values, key: int, target_key: int | None = None
) -> None:
    """Insert (or update) ``key``'s value from ``source`` into ``target``, as ``target_key``
    if given (a Pose2 or a vector: the variables of graphcal's segment graphs)."""
    try:
        value = source.atPose2(key)
    except RuntimeError:
        value = source.atVector(key)
    key = key if target_key is None else target_key
    if target.exists(key):
        target.update(key, value)
    else:
        target.insert(key, value)


def portable(values: gtsam.Values, key: int) -> Portable:
    """``key``'s value in ``values`` as plain data (:func:`restore` puts it back)."""
    try:
        pose = values.atPose2(key)
    except RuntimeError:
        return "vector", np.asarray(values.atVector(key))
    rotation = pose.rotation()
    return "pose2", np.array([pose.x(), pose.y(), rotation.c(), rotation.s()])


def restore(values: gtsam.Values, key: int, value: Portable) -> None:
    """Update ``key`` in ``values`` to a :func:`portable` value, to the bit: a Pose2 travels
    as its rotation's cosine and sine (rebuilt from its angle, they differ in the last bits,
    and so would a result computed with workers from one computed without)."""
    kind, array = value
    if kind == "pose2":
        rotation = gtsam.Rot2.fromCosSin(array[2], array[3])
        values.update(key, gtsam.Pose2(rotation, array[:2]))
    else:
        values.update(key, array)


def tangent_dims(values: gtsam.Values) -> dict[int, int]:
    """Tangent dimension of every variable of ``values``."""
    zero = values.zeroVectors()
    return {int(k): len(zero.at(k)) for k in values.keys()}


def taken_from(initial: gtsam.Values, solution: gtsam.Values) -> gtsam.Values:
    """``initial`` (a graph's own start) with every variable that ``solution`` holds in the
    same tangent dimension taken from it: an earlier solve's values as the start of another
    graph of the same segments, its variables the graph lacks left out."""
    out = gtsam.Values(initial)
    given = tangent_dims(solution)
    for key, dim in tangent_dims(initial).items():
        if given.get(key) == dim:
            copy_value(out, solution, key)
    return out
