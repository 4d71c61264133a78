"""Vectorised reducers of the compiled evaluator (semantics: :mod:`.semantics`).

Arrays are laid out (runs, time, wheel, part, level), size-1 where a value does not vary
along an axis; reductions keep the reduced axis with size 1. ``mask`` (same layout, boolean,
broadcastable) marks the window of a time reduction; ``None`` means every sample.
"""

from __future__ import annotations

import numpy as np


def _full(x: np.ndarray, axis: int, size: int) -> np.ndarray:
    shape = list(x.shape)
    shape[axis] = size
    return np.broadcast_to(x, tuple(shape))


def _as_float(x: np.ndarray) -> np.ndarray:
    return x.astype(float) if x.dtype == bool else x


def _truth(x: np.ndarray) -> np.ndarray:
    return x if x.dtype == bool else x != 0


def reduce(reducer: str, x: np.ndarray, axis: int, size: int, mask: np.ndarray | None = None,
           parameter: np.ndarray | float | None = None,
           t: np.ndarray | None = None) -> np.ndarray:
    """Reduce ``x`` along ``axis`` (length ``size`` once broadcast), keeping the axis."""
    x = _full(np.asarray(x), axis, size)
    if size == 0:
        empty = {"any": False, "all": True}.get(reducer, 0.0)
        shape = list(x.shape)
        shape[axis] = 1
        return np.full(tuple(shape), empty)
    if reducer == "fraction":  # share of true values in the window; an empty window gives 0
        counted = reduce("count", x, axis, size, mask)
        total = (np.asarray(float(size)) if mask is None
                 else np.asarray(_full(mask, axis, size).sum(axis=axis, keepdims=True),
                                 dtype=float))
        return np.asarray(np.where(total > 0, counted / np.maximum(total, 1.0), 0.0))
    if reducer in ("any", "all", "count"):
        truth = _truth(x)
        if mask is None and axis != 1 and size <= _SMALL:
            return _small_axis(reducer, truth, axis, size)
        if reducer == "any":
            return np.asarray((truth if mask is None else truth & mask).any(axis=axis,
                                                                            keepdims=True))
        if reducer == "all":
            return np.asarray((truth if mask is None else truth | ~mask).all(axis=axis,
                                                                             keepdims=True))
        counted = truth if mask is None else truth & mask
        return np.asarray(counted.sum(axis=axis, keepdims=True), dtype=float)
    x = _as_float(x)
    if mask is None:
        if axis != 1 and size <= _SMALL and reducer in _SMALL_REDUCERS:
            return _small_axis(reducer, x, axis, size)
        return _unmasked(reducer, x, axis, size, parameter, t)
    count = mask.sum(axis=axis, keepdims=True)
    empty = count == 0
    if reducer == "max":
        value = np.where(mask, x, -np.inf).max(axis=axis, keepdims=True)
    elif reducer == "min":
        value = np.where(mask, x, np.inf).min(axis=axis, keepdims=True)
    elif reducer == "sum":
        value = np.where(mask, x, 0.0).sum(axis=axis, keepdims=True)
    elif reducer == "mean":
        value = np.where(mask, x, 0.0).sum(axis=axis, keepdims=True) / np.maximum(count, 1)
    elif reducer == "rms":
        value = np.sqrt(np.where(mask, x * x, 0.0).sum(axis=axis, keepdims=True)
                        / np.maximum(count, 1))
    elif reducer in ("final", "initial"):
        full_mask = _full(mask, axis, size)
        if reducer == "final":
            position = size - 1 - np.argmax(np.flip(full_mask, axis=axis), axis=axis)
        else:
            position = np.argmax(full_mask, axis=axis)
        value = _take(x, np.expand_dims(position, axis), axis)
    elif reducer == "integral":
        value = _integral(x, axis, t, mask)
    elif reducer == "time_above":
        value = _time_above(x, axis, t, mask, parameter)
    elif reducer == "percentile":
        value = _percentile(np.where(mask, x, np.inf), count, axis, parameter)
        value = np.where((np.isnan(x) & mask).any(axis=axis, keepdims=True), np.nan, value)
    else:  # pragma: no cover - the checker admits only the reducers above
        raise AssertionError(f"unknown reducer {reducer!r}")
    return np.where(empty, 0.0, value)


def rate(x: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Rate of change along the time axis (axis 1), keeping it: backward differences, the
    forward one at sample 0, 0 where no time passes (semantics in :mod:`.semantics`).

    >>> rate(np.array([[0.0, 1.0, 3.0]]), np.array([0.0, 0.5, 1.5])).tolist()
    [[2.0, 2.0, 2.0]]
    """
    size = len(t)
    x = _full(np.asarray(x, dtype=float), 1, size)
    if size < 2:
        return np.zeros_like(x)
    dt = np.diff(np.asarray(t, dtype=float))
    step = dt.reshape((1, -1) + (1,) * (x.ndim - 2))
    out = np.empty(x.shape)
    slope = out[:, 1:]
    np.subtract(x[:, 1:], x[:, :-1], out=slope)
    with np.errstate(divide="ignore", invalid="ignore"):
        if np.all(dt > 0):
            np.divide(slope, step, out=slope)
        else:
            slope[...] = np.where(step > 0, slope / np.where(step > 0, step, 1.0), 0.0)
    out[:, 0] = out[:, 1]
    return out


# Reducing a short inner axis (4 wheels, 3 parts, 3 levels) with ``ufunc.reduce`` is slow in
# numpy (one tiny reduction per element of the other axes); combining the slices element-wise
# is several times faster and gives the same result.
_SMALL = 8
_SMALL_REDUCERS = frozenset({"max", "min", "sum", "mean", "rms", "final", "initial"})


def _small_axis(reducer: str, x: np.ndarray, axis: int, size: int) -> np.ndarray:
    def part(i: int) -> np.ndarray:
        return x[(slice(None),) * axis + (slice(i, i + 1),)]

    if reducer == "final":
        return part(size - 1).copy()
    if reducer == "initial":
        return part(0).copy()
    if reducer == "rms":
        squares = part(0) * part(0)
        for i in range(1, size):
            squares += part(i) * part(i)
        return np.asarray(np.sqrt(squares / size))
    combine = {"max": np.maximum, "min": np.minimum, "sum": np.add, "mean": np.add,
               "any": np.logical_or, "all": np.logical_and, "count": np.add}[reducer]
    first = part(0)
    result = first.astype(float) if reducer == "count" else first.copy()
    for i in range(1, size):
        combine(result, part(i), out=result)
    return result / size if reducer == "mean" else result


def _unmasked(reducer: str, x: np.ndarray, axis: int, size: int,
              parameter: np.ndarray | float | None, t: np.ndarray | None) -> np.ndarray:
    if reducer == "max":
        return np.asarray(x.max(axis=axis, keepdims=True))
    if reducer == "min":
        return np.asarray(x.min(axis=axis, keepdims=True))
    if reducer == "sum":
        return np.asarray(x.sum(axis=axis, keepdims=True))
    if reducer == "mean":
        return np.asarray(x.mean(axis=axis, keepdims=True))
    if reducer == "rms":
        return np.asarray(np.sqrt((x * x).mean(axis=axis, keepdims=True)))
    if reducer == "final":
        return np.take(x, [size - 1], axis=axis)
    if reducer == "initial":
        return np.take(x, [0], axis=axis)
    if reducer == "integral":
        return _integral(x, axis, t, None)
    if reducer == "time_above":
        return _time_above(x, axis, t, None, parameter)
    if reducer == "percentile":
        value = _whole_percentile(x, size, axis, parameter)
        return np.where(np.isnan(x).any(axis=axis, keepdims=True), np.nan, value)
    raise AssertionError(f"unknown reducer {reducer!r}")  # pragma: no cover


def _take(x: np.ndarray, position: np.ndarray, axis: int) -> np.ndarray:
    shape = np.broadcast_shapes((*x.shape[:axis], 1, *x.shape[axis + 1:]), position.shape)
    x = np.broadcast_to(x, (*shape[:axis], x.shape[axis], *shape[axis + 1:]))
    return np.take_along_axis(x, np.broadcast_to(position, shape), axis=axis)


def _time_shape(values: np.ndarray, ndim: int) -> np.ndarray:
    return values.reshape((1, -1) + (1,) * (ndim - 2))


def _integral(x: np.ndarray, axis: int, t: np.ndarray | None,
              mask: np.ndarray | None) -> np.ndarray:
    assert axis == 1 and t is not None, "integral is a time reduction"
    dt = _time_shape(np.diff(t), x.ndim)
    pieces = 0.5 * (x[:, 1:] + x[:, :-1]) * dt
    if mask is not None:
        pieces = np.where(mask[:, 1:] & mask[:, :-1], pieces, 0.0)
    return np.asarray(pieces.sum(axis=1, keepdims=True))


def _time_above(x: np.ndarray, axis: int, t: np.ndarray | None, mask: np.ndarray | None,
                threshold: np.ndarray | float | None) -> np.ndarray:
    assert axis == 1 and t is not None and threshold is not None, "time_above is over time"
    hold = _time_shape(np.append(np.diff(t), 0.0), x.ndim)
    above = x > threshold
    if mask is not None:
        above = above & mask
    return np.asarray(np.where(above, hold, 0.0).sum(axis=1, keepdims=True))


def _whole_percentile(x: np.ndarray, size: int, axis: int,
                      parameter: np.ndarray | float | None) -> np.ndarray:
    """:func:`_percentile` of every sample: the same rank in every row, so the two order
    statistics come from a partition (linear time) instead of a sort."""
    assert parameter is not None
    rank = float(np.asarray(parameter).reshape(-1)[0]) / 100.0 * (size - 1)
    low = int(np.floor(rank))
    high = min(low + 1, size - 1)
    fraction = rank - low
    parted = np.partition(x, sorted({low, high}), axis=axis)
    below = np.take(parted, [low], axis=axis)
    above = np.take(parted, [high], axis=axis)
    # two equal infinities interpolate to NaN, as in the windowed form and the interpreter:
    # a non-finite value makes the index critical (docs/rulebook-language.md, the table of
    # normalised values)
    with np.errstate(invalid="ignore"):
        return np.asarray(np.where(fraction == 0, below, below + (above - below) * fraction))


def _percentile(x: np.ndarray, count: np.ndarray, axis: int,
                parameter: np.ndarray | float | None) -> np.ndarray:
    """Linear percentile of the first ``count`` sorted values along ``axis`` (out-of-window
    entries were set to +inf so they sort last)."""
    assert parameter is not None
    ordered = np.sort(x, axis=axis)
    rank = float(np.asarray(parameter).reshape(-1)[0]) / 100.0 * (np.maximum(count, 1) - 1)
    low = np.floor(rank).astype(int)
    high = np.minimum(low + 1, np.maximum(count, 1) - 1)
    fraction = rank - low
    below, above = _take(ordered, low, axis), _take(ordered, high, axis)
    with np.errstate(invalid="ignore"):
        return np.where(fraction == 0, below, below + (above - below) * fraction)
