"""Rocks whose face is below the axle (docs/rover-model.md, "Rocks: climbing, pivoting and
stalling"): the wheel meets them with its contact below its axle and climbs them when the push
of the other wheels suffices, P >= W tan(alpha - atan(m mu)); it is never set back while its
motor drives forwards, and where the push does not suffice the rover is `stuck`."""

from __future__ import annotations

import math
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
import soil_model

from idefix_rules.commands import Command
from idefix_rules.fmu import FmuRunner, Rock, source_dir, synthetic_terrain, write_terrain

STRAIGHT = [Command(0.05, 1.0, 0.0)]
RADIUS, WIDTH = soil_model.RADIUS, soil_model.WIDTH
WEAK = 5.0  # Pa, soil.cohesion of the weak regolith


def _mobilised_rock_friction() -> float:
    """m mu at full slip: rock.friction_coefficient 0.6 mobilised by Janosi-Hanamoto over
    the rock.contact_length of 2 cm sheared at slip 1 with rock.shear_K = 1 mm: m = 0.95."""
    return 0.6 * soil_model.janosi(0.02 * 1.0, 0.001)


def _push_over_load(cohesion: float, dug_in: bool = True) -> float:
    """Largest net push (thrust minus compaction) of a driven soil wheel over its load, over all
    slips; `dug_in`: with the steady slip sinkage, otherwise at the static sinkage."""
    load = soil_model.WHEEL_LOAD
    z0 = soil_model.static_sinkage(load, cohesion)
    best = 0.0
    for s in np.linspace(0.01, 1.0, 100):
        z = soil_model.slip_sinkage(z0, s) if dug_in else z0
        push = (soil_model.strength(load, z, cohesion)
                * soil_model.janosi(soil_model.shear_length(z) * s)
                - soil_model.compaction(z, cohesion))
        best = max(best, push / load)
    return best


def _envelope(rock: Rock, wheel_y: float, x: float) -> tuple[float, float, float]:
    """Wheel-centre height over `rock` (solid under its top surface, as the wheel envelope of the
    docs) for a wheel at (x, wheel_y) heading along +x, its contact height and contact angle
    from the vertical: brute force over the footprint, the rim sampled every 0.02° so that a
    contact near the axle is resolved."""
    assert rock.z is not None
    theta = np.radians(np.linspace(-90.0, 90.0, 9001))[:, None]
    d, lift = RADIUS * np.sin(theta), RADIUS * np.cos(theta)
    e = np.linspace(-WIDTH / 2, WIDTH / 2, 61)[None, :]
    q = ((x + d - rock.x) / rock.a) ** 2 + ((wheel_y + e - rock.y) / rock.b) ** 2
    top = np.where(q < 1, rock.z + rock.c * np.sqrt(np.clip(1 - q, 0, None)), -np.inf)
    height = top + lift
    i, j = np.unravel_index(int(np.argmax(height)), height.shape)
    return float(height[i, j]), float(top[i, j]), float(theta[i, 0])


def _first_touch(rock: Rock, wheel_y: float, axle: float) -> tuple[float, float, float]:
    """Contact angle, contact height and wheel-centre x where a wheel rolling along +x at
    y = wheel_y, its axle at `axle` above the flat ground, first touches `rock`."""
    lo, hi = rock.x - rock.a - RADIUS - 0.01, rock.x  # wheel centre: short of the rock, over it
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if _envelope(rock, wheel_y, mid)[0] >= axle else (mid, hi)
    _, top, angle = _envelope(rock, wheel_y, hi)
    return angle, top, hi


def _placed(rock: Rock) -> Rock:
    """The rock with its height resolved on flat ground (z = c: its face is c tall)."""
    return synthetic_terrain(size=1.0, cell=0.1, rocks=[rock]).rocks[0]


def _run(rover: FmuRunner, tmp_path: Path, rock: Rock, **parameters: float
         ) -> dict[str, np.ndarray]:
    terrain = write_terrain(tmp_path / "rock.terrain",
                            synthetic_terrain(size=4.0, cell=0.02, rocks=[rock]))
    return rover.run({"terrain.file": str(terrain), **parameters}, STRAIGHT, 400.0, 0.1,
                     hold_after_chain=False)


def _slip(speed: np.ndarray, rim: np.ndarray) -> np.ndarray:
    """Slip of a wheel whose centre moves at `speed` along its path, its rim at `rim`."""
    return np.where(np.abs(rim) >= np.abs(speed), 1.0 - speed / rim, rim / speed - 1.0)


def _set_back_while_driving_forwards(out: dict[str, np.ndarray]) -> float:
    """Largest fall of x behind its running maximum while the command runs with every motor
    driving forwards (a trim turn on the spot after the command's odometry is not)."""
    forwards = (out["wheel.rate"] > 0).all(axis=1) & (out["command"] >= 0)
    fall = np.maximum.accumulate(out["x"]) - out["x"]
    return float(fall[forwards].max())


@pytest.mark.parametrize("face", [0.06, 0.09])
def test_a_rock_with_its_face_below_the_axle_across_both_front_wheels_is_climbed(
        rover: FmuRunner, tmp_path: Path, face: float) -> None:
    # An ellipsoid 12 cm long and 1 m wide across both front wheels, resting on the ground: its
    # widest section (the face a wheel meets) is `face` high, below the 10 cm axle, and its top
    # twice that. The wheel meets it with the contact below its axle even dug in to its
    # full-slip sinkage, and the rear wheels' push on the default soil (P/W = 8.5) exceeds
    # W tan(alpha - atan(m mu)) at that contact: the rover climbs over it. (Before, a front
    # wheel whose contact had moved up the rock past the height of an axle on the soil lost the
    # rock and dropped into it: the rover stopped, all wheels at full slip, `stuck`.)
    rock = _placed(Rock(0.45, 0.0, 0.06, 0.5, face))
    z0 = soil_model.static_sinkage(soil_model.WHEEL_LOAD)
    alpha, contact, _ = _first_touch(rock, 0.26, RADIUS - soil_model.slip_sinkage(z0, 1.0))
    assert contact < RADIUS - soil_model.slip_sinkage(z0, 1.0) < rock.top
    need = math.tan(alpha - math.atan(_mobilised_rock_friction()))
    assert _push_over_load(soil_model.COHESION) > need

    out = _run(rover, tmp_path, rock)
    assert out["x"][-1] > rock.x + 0.2
    assert out["z"].max() > 0.3 + 0.5 * face  # over the rock, not through it
    assert out["stuck"].max() == 0.0
    assert _set_back_while_driving_forwards(out) <= 1e-3


@pytest.mark.parametrize(("name", "rock", "cohesion"), [
    ("wide 6 cm", Rock(0.45, 0.0, 0.06, 0.5, 0.06), soil_model.COHESION),
    ("wide 8 cm", Rock(0.45, 0.0, 0.06, 0.5, 0.08), soil_model.COHESION),
    ("wide 9.5 cm", Rock(0.45, 0.0, 0.06, 0.5, 0.095), soil_model.COHESION),
    ("right 6 cm", Rock(0.45, -0.26, 0.06, 0.06, 0.06), soil_model.COHESION),
    ("right 9.5 cm", Rock(0.45, -0.26, 0.06, 0.06, 0.095), soil_model.COHESION),
    ("wide 6 cm, weak soil", Rock(0.45, 0.0, 0.06, 0.5, 0.06), WEAK),
])
def test_a_wheel_driving_forwards_is_never_set_back_by_a_rock_below_its_axle(
        rover: FmuRunner, tmp_path: Path, name: str, rock: Rock, cohesion: float) -> None:
    # A wheel whose motor drives forwards climbs, is held, or slides along the rock: the
    # rover never moves backwards (before: 5 mm back at the 8 cm rock). A single rock under the
    # right wheels only is climbed or pivoted past (its face is below the axle): not `stuck`.
    out = _run(rover, tmp_path, rock, **{"soil.cohesion": cohesion})
    assert _set_back_while_driving_forwards(out) <= 1e-3, name
    if rock.y != 0.0:
        assert out["stuck"].max() == 0.0, name


def test_a_rock_the_push_cannot_lift_the_wheels_over_is_stuck(
        rover: FmuRunner, tmp_path: Path) -> None:
    # The 6 cm rock across both front wheels on weak regolith (5 Pa): the wheels meet it at a
    # contact angle 10° beyond what even fresh soil's push lifts them over,
    # a* = atan(m mu) + atan(P/W), so the rover stops on the rock's face, before the contact
    # angle has fallen to a* (the wheel rising on the rock), and is `stuck`.
    rock = _placed(Rock(0.45, 0.0, 0.06, 0.5, 0.06))
    axle = RADIUS - soil_model.static_sinkage(soil_model.WHEEL_LOAD, WEAK)
    alpha, _, touch = _first_touch(rock, 0.26, axle)
    highest = math.atan(_mobilised_rock_friction()) + math.atan(_push_over_load(WEAK, False))
    assert alpha > highest + math.radians(10)
    climbable = touch
    while _envelope(rock, 0.26, climbable)[2] > highest:
        climbable += 0.0005

    out = _run(rover, tmp_path, rock, **{"soil.cohesion": WEAK})
    assert touch - 0.002 < out["x"].max() + 0.2 < climbable  # the front wheels on the face
    assert out["stuck"].max() == 1.0


def test_slip_on_a_rock_is_measured_along_the_path_the_wheel_centre_takes(
        rover: FmuRunner, tmp_path: Path) -> None:
    # Slip is 1 - v/(r omega) driving and r omega/v - 1 skidding (|r omega| < |v|), with v the
    # wheel centre's speed along its path (Wong, Theory of Ground Vehicles, ch. 2). Rolling or
    # sliding on a rigid rock, the hub stays a radius from the contact and moves along the
    # contact's tangent (Iagnemma & Dubowsky 2000; Lamon & Siegwart 2005), so its path is
    # inclined and longer than its horizontal progress. The expectation comes from the outputs
    # alone: a rock 1 m wide across both front wheels keeps the four contacts symmetric, so the
    # least-squares plane passes through them and the front axle's height is
    # z - p_x tan(pitch) above the body's reference; its path speed is
    # hypot(dx/dt, dz_front/dt). While the front wheels climb (the path steeper than 0.2), the
    # reported slip follows it within 0.01 (the finite differences of 0.1 s samples err by
    # about 0.002). Pushed up by the rear wheels, the front wheels skid near the crest (slip
    # about -0.2), where the driving formula would read 0.05 more negative. The former reading,
    # the hub's speed in the body plane, read a rolling wheel on a face inclined by a as
    # 1 - cos a: it differs by more than 0.2 on the steep part of the climb, which this test
    # would catch.
    rock = _placed(Rock(0.45, 0.0, 0.06, 0.5, 0.06))
    out = _run(rover, tmp_path, rock)
    t, x = out["t"], out["x"]
    front = out["z"] - soil_model.HALF_WHEELBASE * np.tan(out["pitch"])
    rim = RADIUS * out["wheel.rate"][:, 0]
    dx, dz = np.gradient(x, t), np.gradient(front, t)
    # the front wheels short of the rock's crest, from 1 s after their first touch (the envelope
    # jumps at the touch within a sample, which finite differences cannot follow)
    rising = (rim > 0.0) & (dx > 1e-5) & (dz > 0.2 * dx) & (x + soil_model.HALF_WHEELBASE < rock.x)
    touch = t[np.argmax(rising)]
    climbing = rising & (t > touch + 1.0)
    assert climbing.sum() > 100  # 10 s of climb at least
    path = _slip(np.hypot(dx, dz)[climbing], rim[climbing])
    body_plane = _slip(dx[climbing], rim[climbing])
    for wheel in (0, 1):  # FL, FR
        slip = out["wheel.slip"][climbing, wheel]
        assert np.abs(slip - path).max() < 0.01
        assert np.abs(slip - body_plane).max() > 0.2


@pytest.fixture(scope="module")
def rock_friction_driver(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """tests/fmu/rock_friction_driver.c compiled with wheel.c and soil.c."""
    compiler = shutil.which("cc") or shutil.which("gcc")
    if compiler is None:
        pytest.skip("no C compiler")
    sources = source_dir() / "sources"
    driver = tmp_path_factory.mktemp("rock_friction") / "rock_friction_driver"
    subprocess.run([compiler, "-std=c99", "-O2", f"-I{sources}",
                    str(Path(__file__).with_name("rock_friction_driver.c")),
                    str(sources / "wheel.c"), str(sources / "soil.c"), "-lm", "-o", str(driver)],
                   check=True)
    return driver


def _rock_forces(driver: Path, angle: float, load: float, rim: float, along: float, vy: float,
                 push: float) -> tuple[float, float, float]:
    """fx, fy and the rim's friction force (the motor's torque over the radius) of a wheel on a
    rock (tests/fmu/rock_friction_driver.c)."""
    out = subprocess.run([str(driver), repr(angle), repr(load), repr(rim), repr(along), repr(vy),
                          repr(push)], capture_output=True, text=True, check=True)
    fx, fy, thrust = (float(v) for v in out.stdout.split())
    return fx, fy, thrust


LOAD = 0.0356  # N, a wheel's share of the weight


@pytest.mark.parametrize("angle", [math.radians(30), math.radians(60), math.radians(-30)])
@pytest.mark.parametrize(("rim", "along", "vy"), [(0.005, 0.001, 0.002), (0.005, 0.005, 0.003),
                                                  (0.0, 0.002, -0.004)])
def test_rock_friction_is_coulomb_on_the_contact_s_normal_force(
        rock_friction_driver: Path, angle: float, rim: float, along: float, vy: float) -> None:
    # A wheel on a rock face tilted by `angle` slides along its path and sideways. Statics of
    # the contact (any text on friction, e.g. Timoshenko & Young): the face pushes with N along
    # its normal and friction T (along the face, in the wheel plane: the rim's torque over its
    # radius) and T_y (across it); the weight W is carried, N cos a + T sin a = W, and what is
    # left along the path is the wheel's force, -N sin a + T cos a = F_x. Coulomb's law holds on
    # N: |(T, T_y)| = mu_m N, with the same mobilised mu_m and direction as the same sliding on
    # a level rock (a = 0, N = W). Taking the load for N, across the wheel and for the torque,
    # was short by N / W (2x at 60° without slip). The other wheels push hard enough (1 N).
    level_x, level_y, level_thrust = _rock_forces(rock_friction_driver, 0.0, LOAD, rim, along,
                                                  vy, 1.0)
    fx, fy, thrust = _rock_forces(rock_friction_driver, angle, LOAD, rim, along, vy, 1.0)
    normal, tangent = np.linalg.solve([[math.cos(angle), math.sin(angle)],
                                       [-math.sin(angle), math.cos(angle)]], [LOAD, fx])
    mobilised = math.hypot(level_x, level_y) / LOAD
    assert level_thrust == pytest.approx(level_x, rel=1e-12)
    assert math.hypot(tangent, fy) == pytest.approx(mobilised * normal, rel=1e-9)
    assert math.atan2(fy, tangent) == pytest.approx(math.atan2(level_y, level_x), abs=1e-9)
    assert thrust == pytest.approx(tangent, rel=1e-9)
    assert abs(normal / LOAD - 1) > 1e-3  # the precondition: N is not the load here


def test_a_face_pushes_back_no_harder_than_the_rover_pushes(rock_friction_driver: Path) -> None:
    # An 80° face, the rim at rest and the hub sliding up and sideways: the friction angle
    # turns the contact force past the vertical and the law reaches its near-rigid stop, where
    # W / cos(angle) is about 100 W. No face pushes back harder than the wheel is pushed into
    # it, at most the other wheels' strength P: N <= cos(atan(m mu)) sqrt(W^2 + P^2), and the
    # friction is Coulomb on that N, in the level rock's direction (before the bound: 49 W
    # sideways with P = 2.8 W).
    angle, rim, along, vy, push = math.radians(80), 0.0, 0.002, -0.004, 0.1
    level_x, level_y, _ = _rock_forces(rock_friction_driver, 0.0, LOAD, rim, along, vy, 1.0)
    fx, fy, thrust = _rock_forces(rock_friction_driver, angle, LOAD, rim, along, vy, push)
    assert abs(fx) > 50 * LOAD  # the precondition: at the stop
    bound = math.cos(math.atan(level_x / LOAD)) * math.hypot(LOAD, push)
    mobilised = math.hypot(level_x, level_y) / LOAD
    assert math.hypot(thrust, fy) == pytest.approx(mobilised * bound, rel=1e-9)
    assert math.atan2(fy, thrust) == pytest.approx(math.atan2(level_y, level_x), abs=1e-9)
