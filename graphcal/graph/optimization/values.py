"""Copying variables between ``gtsam.Values`` and across processes (Pose2 or vector: the
variables of graphcal's segment graphs)."""

from __future__ import annotations

import gtsam
import numpy as np

#: A variable's value as plain data, picklable: ``("pose2", [x, y, cos, sin])`` or
#: ``("vector", array)``.
Portable = tuple[str, np.ndarray]


#: The kind of value (``"pose2"`` or ``"vector"``) last read under each key letter (a key's
#: top byte, GTSAM's ``Symbol``): read first as that kind, the other only if that fails. A
#: failed ``atPose2`` raises through pybind11 at ~17 µs, most of the cost of copying a long
#: log's 23,000 vector variables into its parts (0.43 of 0.78 s on a 24 km drive's run).
_KIND_OF_LETTER: dict[int, str] = {}


def _read(values: gtsam.Values, key: int) -> tuple[str, object]:
    """``key``'s kind and value in ``values`` (a Pose2 or a vector)."""
    letter = key >> 56
    kinds = ("vector", "pose2") if _KIND_OF_LETTER.get(letter) == "vector" else ("pose2", "vector")
    try:
        kind, value = kinds[0], _at(values, key, kinds[0])
    except RuntimeError:
        kind, value = kinds[1], _at(values, key, kinds[1])
    _KIND_OF_LETTER[letter] = kind
    return kind, value


def _at(values: gtsam.Values, key: int, kind: str) -> object:
    return values.atPose2(key) if kind == "pose2" else values.atVector(key)


def copy_value(
    target: gtsam.Values, source: gtsam.Values, key: int, target_key: int | None = None
) -> None:
    """Insert (or update) ``key``'s value from ``source`` into ``target``, as ``target_key``
    if given (a Pose2 or a vector: the variables of graphcal's segment graphs)."""
    value = _read(source, key)[1]
    key = key if target_key is None else target_key
    if target.exists(key):
        target.update(key, value)
    else:
        target.insert(key, value)


def portable(values: gtsam.Values, key: int) -> Portable:
    """``key``'s value in ``values`` as plain data (:func:`restore` puts it back)."""
    kind, value = _read(values, key)
    if kind == "vector":
        return "vector", np.asarray(value)
    rotation = value.rotation()
    return "pose2", np.array([value.x(), value.y(), rotation.c(), rotation.s()])


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
