"""What a worst-case search found, as data: ``worst.json`` (docs/worst-case.md).

Per path: the nominal world and the worst world found (each parameter's value, quantile and
standard-normal coordinate; its run risk and dominant index; its distance from the nominal
world and how rare such a world is), the parameters the risk is most sensitive to, the failure
boundary along each ray searched, and the smallest change from the nominal world found to make
the chain critical. Values are SI, risks and probabilities fractions, as in ``summary.json``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from idefix_rules.campaign.worst.boundary import Ray
from idefix_rules.campaign.worst.search import BOUNDARY, SEARCH, PathSearch, Point
from idefix_rules.campaign.worst.space import QuantileSpace, distance, one_in

FORMAT = "idefix-worst"
FORMAT_VERSION = 1
METHOD = ("cross-entropy search of the run risk I_max in standard-normal quantile "
          "coordinates, then a grid bisection of the failure boundary along rays from the "
          "nominal world")


def rarity(probability: float) -> str:
    """A world's tail probability as people read it: a percentage down to 1 %, then
    ``1 in N``.

    >>> rarity(0.943), rarity(0.0133), rarity(0.000127)
    ('94 %', '1.3 %', '1 in 7,900')
    """
    if probability >= 0.1:
        return f"{probability:.0%}".replace("%", " %")
    if probability >= 0.01:
        return f"{100 * probability:.1f} %"
    return one_in(probability)


def sigmas(distance: float) -> str:
    """A distance in the quantile coordinates' standard deviations, to 3 digits.

    >>> sigmas(0.0468), sigmas(4.021), sigmas(0.0)
    ('0.0468 σ', '4.02 σ', '0 σ')
    """
    return f"{distance:.3g} σ"


def _round(value: float | None, digits: int = 4) -> float | None:
    if value is None or not math.isfinite(value):
        return None
    return round(float(value), digits)


def _significant(value: float, digits: int = 4) -> float:
    return float(f"{value:.{digits}g}")


def world_record(space: QuantileSpace, origin: np.ndarray, z: np.ndarray, risk: float | None,
                 dominant: str | None, run: int | None) -> dict[str, Any]:
    """One world: its row (None: the reference run), risk, dominant index, every uncertain
    parameter's value (SI), quantile and coordinate, its distance from the nominal world (in
    standard deviations of the coordinates) and the share of campaign worlds at least as far
    from the median world (``tail_probability``, with ``one_in`` for people)."""
    values = space.values(z)
    quantiles = space.quantiles(np.asarray(z))
    tail = space.tail_probability(z)
    return {
        "run": run,
        "risk": _round(risk),
        "dominant_index": dominant,
        "parameters": {name: {"value": _significant(float(values[name][0]), 6),
                              "quantile": _significant(float(quantiles[column]), 4),
                              "z": round(float(z[column]), 3)}
                       for column, name in enumerate(space.names)},
        "distance": round(float(distance(z, origin)[0]), 3),
        "tail_probability": _significant(tail, 3),
        "one_in": one_in(tail),
    }


def _point_record(space: QuantileSpace, origin: np.ndarray, point: Point) -> dict[str, Any]:
    return world_record(space, origin, point.z, point.risk, point.dominant,
                        None if point.row < 0 else point.row)


def _ray_point(search: PathSearch, number: int, step: float) -> Point | None:
    """The simulated point of ray ``number`` at ``step`` (None: the nominal world)."""
    if step <= 0.0:
        return None
    ray = search.rays[number]
    target = ray.point(step)
    for point in search.points:
        if point.ray == number and np.allclose(point.z, target, atol=1e-9):
            return point
    worst = search.worst
    return worst if np.allclose(worst.z, target, atol=1e-9) else None


def boundary_record(search: PathSearch, number: int) -> dict[str, Any]:
    """The failure boundary along one ray: found or not, its distance from the nominal world
    (the first critical world simulated), the bracket it lies in, the critical world and the
    last world before it that was not critical."""
    ray: Ray = search.rays[number]
    space, origin = search.space, search.origin
    runs = sum(1 for point in search.points if point.ray == number)
    record: dict[str, Any] = {
        "direction": ray.label, "parameter": ray.axis,
        "unit_vector": [round(float(v), 4) for v in ray.direction],
        "searched_to": round(ray.end, 3), "runs": runs, "found": False,
        "distance": None, "bracket": None, "critical_world": None, "last_safe_world": None}
    bracket = ray.bracket
    if bracket is None:
        return record
    low, high = bracket
    critical = _ray_point(search, number, high)
    safe = _ray_point(search, number, low)
    record.update({
        "found": True, "distance": round(high, 4), "bracket": [round(low, 4), round(high, 4)],
        "critical_world": _point_record(space, origin, critical) if critical else None,
        "last_safe_world": _point_record(space, origin, safe) if safe is not None
        else world_record(space, origin, origin, search.nominal_risk, search.nominal_dominant,
                          None)})
    return record


def path_record(name: str, search: PathSearch) -> dict[str, Any]:
    """Everything found for one searched path."""
    space, origin, settings = search.space, search.origin, search.settings
    worst = search.worst
    risks = np.array([p.risk for p in search.points], dtype=float)
    generations = []
    for generation in sorted({p.generation for p in search.points if p.phase == SEARCH
                              and p.generation is not None}):
        rows = [p for p in search.points if p.phase == SEARCH and p.generation == generation]
        found = [p.risk for p in rows if math.isfinite(p.risk)]
        generations.append({"generation": generation, "rows": [rows[0].row, rows[-1].row + 1],
                            "highest_risk": _round(max(found)) if found else None})
    boundaries = [boundary_record(search, number) for number in range(len(search.rays))]
    nominal_critical = search.critical(search.nominal_risk)
    return {
        "name": name, "status": "searched", "reason": "",
        "runs_used": search.used,
        "search_runs": sum(1 for p in search.points if p.phase == SEARCH),
        "boundary_runs": sum(1 for p in search.points if p.phase == BOUNDARY),
        "failed_runs": int(np.sum(~np.isfinite(risks))),
        "generations": generations,
        "nominal": world_record(space, origin, origin, search.nominal_risk,
                                search.nominal_dominant, None),
        "worst": _point_record(space, origin, worst),
        "critical": search.critical(worst.risk),
        "nominal_critical": nominal_critical,
        "sensitivity": [{"parameter": a.parameter, "rho": round(a.rho, 3),
                         "significant": a.significant} for a in search.axes],
        "boundaries": boundaries,
        "smallest_change": smallest_change(boundaries, nominal_critical),
        "threshold": settings.threshold,
    }


def smallest_change(boundaries: Sequence[Mapping[str, Any]],
                    nominal_critical: bool) -> dict[str, Any] | None:
    """The boundary nearest to the nominal world among the rays searched (distance 0 when
    the nominal world is critical already); None when no ray found one."""
    if nominal_critical:
        return {"direction": None, "distance": 0.0, "world": None}
    found = [b for b in boundaries if b["found"]]
    if not found:
        return None
    nearest = min(found, key=lambda b: (b["distance"], b["direction"]))
    return {"direction": nearest["direction"], "distance": nearest["distance"],
            "world": nearest["critical_world"]}


def skipped_record(name: str, status: str, reason: str) -> dict[str, Any]:
    """A path the search could not look at (rejected by a command rule, excluded by the
    pre-screen, its reference run failed)."""
    return {"name": name, "status": status, "reason": reason, "runs_used": 0}


def parameter_records(space: QuantileSpace, units: Mapping[str, str],
                      distributions: Mapping[str, str]) -> list[dict[str, Any]]:
    origin = space.nominal()
    nominal = space.values(origin)
    return [{"name": name, "unit": units.get(name, ""), "distribution": distributions.get(name),
             "nominal": _significant(float(nominal[name][0]), 6),
             "nominal_quantile": _significant(float(space.quantiles(origin)[column]), 4)}
            for column, name in enumerate(space.names)]
