"""The rover as separate collision bodies: four wheels, the chassis, two solar panels.

Frames: x forward, y left, z up. A pose is ``x, y, z, roll, pitch, yaw`` with the rotation
``R = Rz(yaw) · Ry(pitch) · Rx(roll)`` (aerospace order, the rover FMU uses the same): positive
roll lowers the right side, positive pitch lowers the nose. Pose ``z`` is the body-centre height
above the terrain datum; the body centre is the centre of the chassis box.

Dimensions (defaults, see ``docs/obstacles.md`` for the sources and assumptions): wheel centres at
``(±half_wheelbase, ±half_track)`` from :class:`idefix_rules.commands.RoverGeometry`, wheel radius
from the same place; the chassis is the rover FMU's 0.41 × 0.37 × 0.30 m box with an assumed
0.15 m ground clearance in the driving leg pose, so the wheel axles sit 0.20 m below the body
centre; each solar panel is a thin box hinged at the top edge of a chassis side, spread outwards.

>>> bodies = RoverBodies()
>>> [b.name for b in bodies.bodies()]
['FL', 'FR', 'RL', 'RR', 'chassis', 'panel_left', 'panel_right']
>>> round(bodies.body_centre_height, 3)
0.3
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from idefix_rules.commands import WHEELS, RoverGeometry
from idefix_rules.errors import UserInputError, error
from idefix_rules.signals import AXIS_LABELS

PARTS: tuple[str, ...] = AXIS_LABELS["part"]
_DEFAULT_GEOMETRY = RoverGeometry()


def rotation_matrices(roll: np.ndarray, pitch: np.ndarray, yaw: np.ndarray) -> np.ndarray:
    """``Rz(yaw) · Ry(pitch) · Rx(roll)`` for arrays of angles, shape ``angles.shape + (3, 3)``.

    >>> r = rotation_matrices(np.array(0.0), np.array(0.0), np.array(np.pi / 2))
    >>> np.round(r @ [1.0, 0.0, 0.0], 6).tolist()
    [0.0, 1.0, 0.0]
    """
    roll, pitch, yaw = np.broadcast_arrays(np.asarray(roll, float), np.asarray(pitch, float),
                                           np.asarray(yaw, float))
    cr, sr = np.cos(roll), np.sin(roll)
    cp, sp = np.cos(pitch), np.sin(pitch)
    cy, sy = np.cos(yaw), np.sin(yaw)
    out = np.empty((*roll.shape, 3, 3))
    out[..., 0, 0] = cy * cp
    out[..., 0, 1] = cy * sp * sr - sy * cr
    out[..., 0, 2] = cy * sp * cr + sy * sr
    out[..., 1, 0] = sy * cp
    out[..., 1, 1] = sy * sp * sr + cy * cr
    out[..., 1, 2] = sy * sp * cr - cy * sr
    out[..., 2, 0] = -sp
    out[..., 2, 1] = cp * sr
    out[..., 2, 2] = cp * cr
    return out


def quaternions(roll: np.ndarray, pitch: np.ndarray, yaw: np.ndarray) -> np.ndarray:
    """Unit quaternions ``(w, x, y, z)`` of the same rotations as :func:`rotation_matrices`,
    shape ``angles.shape + (4,)`` (python-fcl takes rotations fastest in this form)."""
    hr, hp, hy = np.asarray(roll, float) / 2, np.asarray(pitch, float) / 2, \
        np.asarray(yaw, float) / 2
    cr, sr, cp, sp, cy, sy = np.cos(hr), np.sin(hr), np.cos(hp), np.sin(hp), np.cos(hy), \
        np.sin(hy)
    return np.stack([cy * cp * cr + sy * sp * sr,
                     cy * cp * sr - sy * sp * cr,
                     cy * sp * cr + sy * cp * sr,
                     sy * cp * cr - cy * sp * sr], axis=-1)


def quaternion_product(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product ``a ⊗ b`` (rotation ``a`` after ``b``) of quaternion arrays."""
    w1, x1, y1, z1 = np.moveaxis(np.asarray(a, float), -1, 0)
    w2, x2, y2, z2 = np.moveaxis(np.asarray(b, float), -1, 0)
    return np.stack([w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
                     w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                     w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
                     w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2], axis=-1)


def _rot_x(angle: float) -> np.ndarray:
    return rotation_matrices(np.array(angle), np.array(0.0), np.array(0.0))


@dataclass(frozen=True, eq=False)
class Body:
    """One rigid collision body in the rover body frame.

    ``shape`` is ``"cylinder"`` (``size = (radius, width)``, axis along the body's y) or ``"box"``
    (``size`` = full lengths along the body's own x, y, z). ``offset``/``rotation`` place the
    body's own frame in the rover body frame. ``radius`` bounds the body about its centre and
    ``reach`` bounds every point of it about the rover body centre (used for motion bounds).
    """

    name: str
    part: int  # index into PARTS
    shape: str
    size: tuple[float, ...]
    offset: np.ndarray
    rotation: np.ndarray
    tilt: float = 0.0  # the rotation as an angle about the body x axis

    @cached_property
    def quaternion(self) -> np.ndarray:
        return quaternions(np.array(self.tilt), np.array(0.0), np.array(0.0))

    @property
    def radius(self) -> float:
        if self.shape == "cylinder":
            return math.hypot(self.size[0], self.size[1] / 2.0)
        return 0.5 * math.sqrt(sum(s * s for s in self.size))

    @property
    def reach(self) -> float:
        return float(np.linalg.norm(self.offset)) + self.radius


@dataclass(frozen=True)
class RoverBodies:
    """Dimensions of the rover's collision bodies, in metres and radians.

    Defaults: wheel radius, half track and half wheelbase from
    :class:`~idefix_rules.commands.RoverGeometry` (the rover FMU's defaults); the chassis box is
    the rover FMU's body; wheel width, ground clearance and the solar panels are assumptions
    (``docs/obstacles.md``).
    """

    wheel_radius: float = _DEFAULT_GEOMETRY.wheel_radius
    wheel_width: float = 0.06
    half_track: float = _DEFAULT_GEOMETRY.half_track
    half_wheelbase: float = _DEFAULT_GEOMETRY.half_wheelbase
    chassis_length: float = 0.41
    chassis_width: float = 0.37
    chassis_height: float = 0.30
    ground_clearance: float = 0.15
    panel_length: float = 0.37
    panel_span: float = 0.20
    panel_thickness: float = 0.02
    panel_droop: float = 0.0

    def __post_init__(self) -> None:
        lengths = {
            "wheel_radius": self.wheel_radius, "wheel_width": self.wheel_width,
            "half_track": self.half_track, "half_wheelbase": self.half_wheelbase,
            "chassis_length": self.chassis_length, "chassis_width": self.chassis_width,
            "chassis_height": self.chassis_height, "panel_length": self.panel_length,
            "panel_span": self.panel_span, "panel_thickness": self.panel_thickness,
        }
        problems = [error("E601", f"rover body dimension {name} must be a positive length in m, "
                                  f"got {value!r}")
                    for name, value in lengths.items()
                    if not (isinstance(value, int | float) and math.isfinite(value) and value > 0)]
        if not (math.isfinite(self.ground_clearance) and self.ground_clearance >= 0):
            problems.append(error("E601", "ground_clearance must be a length >= 0 m, "
                                          f"got {self.ground_clearance!r}"))
        if problems:
            raise UserInputError(problems)

    @classmethod
    def from_geometry(cls, geometry: RoverGeometry, **overrides: float) -> RoverBodies:
        """Bodies whose wheels match a :class:`RoverGeometry` (the kinematics' geometry)."""
        return cls(wheel_radius=geometry.wheel_radius, half_track=geometry.half_track,
                   half_wheelbase=geometry.half_wheelbase, **overrides)

    @property
    def body_centre_height(self) -> float:
        """Height of the body centre above flat ground under the wheels (pose ``z`` on flat
        ground at datum 0, ignoring sinkage)."""
        return self.ground_clearance + self.chassis_height / 2.0

    def bodies(self) -> tuple[Body, ...]:
        """The collision bodies in the order FL, FR, RL, RR, chassis, left panel, right panel."""
        axle_z = self.wheel_radius - self.body_centre_height
        wheel_rotation = _rot_x(math.pi / 2.0)  # cylinder axis (own z) along the body's y
        out = []
        for name in WHEELS:
            sx = 1.0 if name[0] == "F" else -1.0
            sy = 1.0 if name[1] == "L" else -1.0
            out.append(Body(name, PARTS.index("wheel"), "cylinder",
                            (self.wheel_radius, self.wheel_width),
                            np.array([sx * self.half_wheelbase, sy * self.half_track, axle_z]),
                            wheel_rotation, math.pi / 2.0))
        out.append(Body("chassis", PARTS.index("chassis"), "box",
                        (self.chassis_length, self.chassis_width, self.chassis_height),
                        np.zeros(3), np.eye(3)))
        top = self.chassis_height / 2.0
        for name, side in (("panel_left", 1.0), ("panel_right", -1.0)):
            # Hinged at the top edge of the chassis side, drooping by panel_droop below level.
            rotation = _rot_x(-side * self.panel_droop)
            hinge = np.array([0.0, side * self.chassis_width / 2.0, top])
            centre = hinge + rotation @ np.array([0.0, side * self.panel_span / 2.0,
                                                  -self.panel_thickness / 2.0])
            out.append(Body(name, PARTS.index("solar_panel"), "box",
                            (self.panel_length, self.panel_span, self.panel_thickness),
                            centre, rotation, -side * self.panel_droop))
        return tuple(out)

    @property
    def reach(self) -> float:
        """Radius of a sphere about the body centre holding every body."""
        return max(body.reach for body in self.bodies())
