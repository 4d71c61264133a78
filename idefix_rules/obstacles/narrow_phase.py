"""The collision check's narrow phase: conservative advancement along one stretch, with fcl."""

from __future__ import annotations

import math
from bisect import bisect_right
from collections.abc import Callable

import fcl
import numpy as np

from idefix_rules.obstacles.bodies import PARTS, Body, quaternion_product, quaternions
from idefix_rules.obstacles.chunks import Tracks
from idefix_rules.obstacles.distances import (
    body_point_near,
    certified_distance,
    fcl_body,
    fcl_piece,
    piece_inside,
    piece_support,
    support_function,
)
from idefix_rules.obstacles.obstacles import LEVELS, ObstacleSet, Piece
from idefix_rules.obstacles.result import CheckSettings, FirstContact


class Walker:
    """Conservative advancement along one (run, body, piece) stretch, writing into tracks."""

    def __init__(self, chunk: dict[str, np.ndarray], rotation: np.ndarray, position: np.ndarray,
                 cum: np.ndarray, body_list: tuple[Body, ...], pieces: list[Piece],
                 piece_owner: np.ndarray, obstacles: ObstacleSet, settings: CheckSettings,
                 cap: float, tracks: Tracks) -> None:
        self.chunk, self.rotation, self.position, self.cum = chunk, rotation, position, cum
        self.body_list, self.piece_owner = body_list, piece_owner
        self.obstacles, self.settings, self.cap, self.tracks = obstacles, settings, cap, tracks
        self.body_objects = [fcl_body(b) for b in body_list]
        self.piece_objects = [fcl_piece(p) for p in pieces]
        self.body_supports = [support_function(b.shape, b.size) for b in body_list]
        self.piece_supports = [piece_support(p) for p in pieces]
        self.exact = [p.shape == "sphere" for p in pieces]  # fcl has closed forms for these
        self.pieces = pieces
        self.piece_insides = [piece_inside(p) for p in pieces]
        self.body_nears = [body_point_near(b) for b in body_list]
        self.request = fcl.DistanceRequest()

    def _measurer(self, b: int, m: int, margin: float) -> Callable[[], tuple[float, float]]:
        """``measure() -> (value, allowance)`` at body ``b``'s current pose against piece ``m``:
        value is the clearance (0 in contact, capped), allowance how far (in ``u``) every
        decision and the clearance value within its error bound are sure to hold."""
        settings, tol, cap = self.settings, self.settings.contact_tolerance, self.cap
        min_step = settings.min_step
        resolution, relative = settings.clearance_resolution, settings.clearance_relative
        check_margin = margin > tol
        body_object, piece_object = self.body_objects[b], self.piece_objects[m]
        body_support, piece_world = self.body_supports[b], self.piece_supports[m]
        exact = self.exact[m]
        inside, near = self.piece_insides[m], self.body_nears[b]
        cx, cy, cz = np.asarray(self.pieces[m].centre, float).tolist()
        distance_of, new_result, request = fcl.distance, fcl.DistanceResult, self.request

        def measure() -> tuple[float, float]:
            if exact:
                distance = distance_of(body_object, piece_object, request, new_result())
                uncertain = 0.0
            else:  # GJK: the exact distance lies in [distance - uncertain, distance]
                distance, lower = certified_distance(body_object, body_support, piece_object,
                                                     piece_world, min_step)
                uncertain = distance - lower
            if distance <= tol:
                if distance > 0.0:
                    return 0.0, tol - distance
                # fcl reports -1 for overlap. A point q of the body inside the piece with a
                # ball of radius s around it inside too keeps the overlap while every point of
                # the body moves less than s, and the contact (distance ≤ tol) for s + tol.
                # q: the point of the body nearest the piece's centre.
                witness = inside(*near(body_object, cx, cy, cz))
                return 0.0, tol + (witness if witness > 0.0 else 0.0)
            # Keep the contact and buffer decisions, bound the clearance error.
            allowance = distance - tol
            if check_margin:
                to_margin = distance - margin if distance > margin else margin - distance
                if to_margin < allowance:
                    allowance = to_margin
            error_bound = relative * distance
            if error_bound < resolution:
                error_bound = resolution
            if distance - cap > error_bound:
                error_bound = distance - cap
            if error_bound < allowance:
                allowance = error_bound
            allowance -= uncertain  # every bound above holds from the lower end as well
            return (distance if distance < cap else cap), (
                allowance if allowance > min_step else min_step)

        return measure

    def walk(self, run: int, b: int, m: int, first: int, last: int) -> None:
        """Anchors at samples as far apart as their allowances permit; a gap between two
        consecutive samples is filled with interpolated anchors only when a contact or buffer
        entry could hide in it (both ends clear of a threshold, but not by enough)."""
        tol = self.settings.contact_tolerance
        body, body_object = self.body_list[b], self.body_objects[b]
        owner = int(self.piece_owner[m])
        margin = self.obstacles.buffer_margins[self.obstacles.obstacles[owner].level]
        measure = self._measurer(b, m, margin)
        span = slice(first, last + 1)
        cum = self.cum[run, span, b].tolist()
        rotations = quaternion_product(
            quaternions(self.chunk["roll"][run, span], self.chunk["pitch"][run, span],
                        self.chunk["yaw"][run, span]), body.quaternion)
        positions = self.position[run, span] + self.rotation[run, span] @ body.offset
        set_rotation, set_translation = body_object.setQuatRotation, body_object.setTranslation
        end = last - first
        values: list[float] = []
        counts: list[int] = []
        between: list[int] = []  # samples marked for contacts found between two samples
        fill_min = self.cap
        set_rotation(rotations[0])
        set_translation(positions[0])
        value, allowance = measure()
        first_contact: tuple[int, float] | None = (0, 0.0) if value == 0.0 else None
        j = 0
        while True:
            k = bisect_right(cum, cum[j] + allowance) - 1
            values.append(value)
            if k >= end:
                counts.append(end - j + 1)
                break
            if k > j:  # samples j..k-1 are covered by the anchor at j
                counts.append(k - j)
                j = k
                set_rotation(rotations[j])
                set_translation(positions[j])
                value, allowance = measure()
                if value == 0.0 and first_contact is None:
                    first_contact = (j, 0.0)
                continue
            counts.append(1)  # the next sample lies beyond the allowance: measure it too
            set_rotation(rotations[j + 1])
            set_translation(positions[j + 1])
            next_value, next_allowance = measure()
            step = cum[j + 1] - cum[j]
            if _gap_may_hide(value, next_value, step, tol, margin):
                low, contact_at = self._fill(run, body, first + j, measure, cum[j] + allowance,
                                             cum[j + 1] - next_allowance, cum[j], step)
                fill_min = min(fill_min, low)
                if contact_at is not None:
                    between.append(j if contact_at < 0.5 else j + 1)
                    if first_contact is None:
                        first_contact = (j, contact_at)
            j += 1
            value, allowance = next_value, next_allowance
            if value == 0.0 and first_contact is None:
                first_contact = (j, 0.0)
        self._record(run, b, owner, first, np.repeat(values, counts), between, first_contact,
                     fill_min)

    def _fill(self, run: int, body: Body, sample: int, measure: Callable[[], tuple[float, float]],
              u: float, u_end: float, u_sample: float, step: float) -> tuple[float, float | None]:
        """Interpolated anchors from ``u`` to ``u_end`` between ``sample`` and the next one:
        the smallest clearance seen and the fraction of the step where contact starts, if any."""
        body_object = self.body_objects[self.body_list.index(body)]
        low = self.cap
        while u < u_end:
            frac = (u - u_sample) / step
            quaternion, position = self._pose_between(run, sample, frac, body)
            body_object.setQuatRotation(quaternion)
            body_object.setTranslation(position)
            value, allowance = measure()
            low = min(low, value)
            if value == 0.0:
                return 0.0, frac
            u += allowance
        return low, None

    def _pose_between(self, run: int, sample: int, frac: float, body: Body
                      ) -> tuple[np.ndarray, np.ndarray]:
        """Quaternion and position of ``body`` at the pose interpolated linearly between two
        samples (the motion bound assumes exactly this interpolation); plain floats, as this
        runs once per interpolated anchor."""
        c = self.chunk

        def lerp(name: str) -> float:
            a = float(c[name][run, sample])
            return a + frac * (float(c[name][run, sample + 1]) - a)

        roll, pitch, yaw = lerp("roll") / 2, lerp("pitch") / 2, lerp("yaw") / 2
        cr, sr, cp, sp = math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch)
        cy, sy = math.cos(yaw), math.sin(yaw)
        w = cy * cp * cr + sy * sp * sr
        x = cy * cp * sr - sy * sp * cr
        y = cy * sp * cr + sy * cp * sr
        z = sy * cp * cr - cy * sp * sr
        ox, oy, oz = (float(v) for v in body.offset)
        # v + 2w (q × v) + 2 q × (q × v): the offset rotated by the pose.
        tx, ty, tz = 2 * (y * oz - z * oy), 2 * (z * ox - x * oz), 2 * (x * oy - y * ox)
        px = lerp("x") + ox + w * tx + (y * tz - z * ty)
        py = lerp("y") + oy + w * ty + (z * tx - x * tz)
        pz = lerp("z") + oz + w * tz + (x * ty - y * tx)
        bw, bx, by, bz = (float(v) for v in body.quaternion)
        quaternion = np.array([w * bw - x * bx - y * by - z * bz,
                               w * bx + x * bw + y * bz - z * by,
                               w * by - x * bz + y * bw + z * bx,
                               w * bz + x * by - y * bx + z * bw])
        return quaternion, np.array([px, py, pz])

    def _record(self, run: int, b: int, owner: int, first: int, per_sample: np.ndarray,
                between: list[int], first_contact: tuple[int, float] | None,
                fill_min: float) -> None:
        tracks = self.tracks
        body = self.body_list[b]
        span = slice(first, first + len(per_sample))
        np.minimum(tracks.clearance[run, span, b], per_sample, out=tracks.clearance[run, span, b])
        part = body.part
        tracks.nearest[run, b, owner] = min(tracks.nearest[run, b, owner],
                                            float(per_sample.min()), fill_min)
        if first_contact is None:
            return
        level = self.obstacles.obstacles[owner].level
        touching = np.concatenate([np.flatnonzero(per_sample == 0.0), between]).astype(int)
        tracks.contact[run, touching + first, part, level] = 1
        tracks.clearance[run, touching + first, b] = 0.0
        tracks.hit[run, b, owner] = True
        j, frac = first_contact
        sample = first + j
        nxt = min(sample + 1, self.chunk["t"].shape[1] - 1)
        pose = {name: (1 - frac) * float(self.chunk[name][run, sample])
                + frac * float(self.chunk[name][run, nxt]) for name in ("t", "x", "y", "z")}
        tracks.note_contact(FirstContact(PARTS[part], LEVELS[level], pose["t"], pose["x"],
                                         pose["y"], pose["z"], body.name,
                                         self.obstacles.obstacles[owner].name), run)


def _gap_may_hide(value: float, next_value: float, step: float, tol: float,
                  margin: float) -> bool:
    """Whether a contact or buffer entry could lie strictly between two measured samples that
    both show none: the distance can dip at most to ``(d0 + d1 - step) / 2`` in between."""
    if value == 0.0 or next_value == 0.0:
        return False  # a contact at either end already counts
    lowest = (value + next_value - step) / 2.0
    if lowest <= tol:
        return True
    return margin > tol and value >= margin and next_value >= margin and lowest < margin
