"""Rock contact and wheel loads (docs/rover-model.md, "Rocks" and "Loads"): a face above the
axle is a one-sided constraint, a blocked wheel a pivot, and loads follow the ground's twist."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import soil_model

from idefix_rules.commands import Command
from idefix_rules.fmu import FmuRunner, Rock, synthetic_terrain, write_terrain

ODOMETRY = {"controller.heading_feedback": 0.0}
STRAIGHT = [Command(0.05, 1.0, 0.0)]
WHEELS = ("FL", "FR", "RL", "RR")


def _terrain(tmp_path: Path, rock: Rock, name: str) -> str:
    return str(write_terrain(tmp_path / name, synthetic_terrain(size=4.0, cell=0.02,
                                                                rocks=[rock])))


def _loads(out: dict[str, np.ndarray]) -> np.ndarray:
    return np.stack([out[f"wheel.{w}.load"] for w in WHEELS], axis=1)


def _longest_still_while_driving(out: dict[str, np.ndarray]) -> int:
    """Longest run of samples in which the pose did not change at all while a wheel turned."""
    still = (np.diff(out["x"]) == 0) & (np.diff(out["y"]) == 0) & (np.diff(out["yaw"]) == 0)
    driving = np.abs(out["wheel.rate"][1:]).max(axis=1) > 0
    longest = current = 0
    for frozen in still & driving:
        current = current + 1 if frozen else 0
        longest = max(longest, current)
    return longest


def test_a_tall_rock_in_one_track_turns_the_rover_to_its_side_and_is_never_entered(
        rover: FmuRunner, tmp_path: Path) -> None:
    # A 15 cm rock (taller than the 10 cm axle) in the right wheels' track only, half buried: a
    # dome the front right wheel first touches at 77°, 7.6 cm high, below its axle. Its support
    # is the contact, r sin 77° = 9.7 cm ahead of the hub (docs/rover-model.md, "Loads"), so the
    # FR-RL diagonal passes 5 cm left of the centre of gravity and the chassis rests on FR, RL
    # and RR (RR about 14 mN): RR pushes in line behind the front right wheel, which climbs over
    # the rock's flank. The rear right wheel then meets the rock, its contact 9.7 cm ahead of
    # its hub, inside the rectangle: the chassis rests on RR, FL and RL, FR unloaded, and RR is
    # pushed only by FL and RL, whose push turns the chassis about it: the rover yaws and drifts
    # towards the held (right) side (the paper: "the wheel ... get stuck and the rover to drift
    # to the right"). Open loop, as a rover without heading control.
    terrain = _terrain(tmp_path, Rock(0.55, -0.26, 0.06, 0.06, 0.15, z=0.0), "tall.terrain")
    out = rover.run({**ODOMETRY, "terrain.file": terrain}, STRAIGHT, 250.0, 0.1)
    assert out["yaw"].min() < math.radians(-5)  # towards the blocked side, clearly
    assert out["y"][-1] < -0.03
    assert out["x"][-1] > 0.5  # the front right wheel past the rock
    assert _longest_still_while_driving(out) <= 2  # never frozen while the wheels turn
    # the front right wheel is never in the rock: its centre stays outside the rock's section
    # at the height of its axle by half its width. On flat ground, with the other three wheels
    # out of the rock's reach (on the soil, their contacts at -sinkage), the mean contact height
    # z - 0.30 m gives the front right one's: h_FR = 4 (z - 0.30) + z_FL + z_RL + z_RR.
    c, s = np.cos(out["yaw"]), np.sin(out["yaw"])
    reach = 0.06 + soil_model.RADIUS + soil_model.WIDTH / 2
    others_off = np.ones(len(c), dtype=bool)
    for px, py in ((0.20, 0.26), (-0.20, 0.26), (-0.20, -0.26)):  # FL, RL, RR
        others_off &= np.hypot(out["x"] + px * c - py * s - 0.55,
                               out["y"] + px * s + py * c + 0.26) > reach
    sinkage = out["wheel.sinkage"]
    axle = 4 * (out["z"] - 0.30) + sinkage[:, [0, 2, 3]].sum(axis=1) + soil_model.RADIUS
    fr_x, fr_y = out["x"] + 0.20 * c + 0.26 * s, out["y"] + 0.20 * s - 0.26 * c
    past = int(np.argmax(fr_x > 0.55 + 0.06 + soil_model.RADIUS))
    assert past > 0 and others_off[:past].all()  # the others off the rock until FR is past
    section = 0.06 * np.sqrt(np.clip(1 - (axle / 0.15) ** 2, 0, None))
    clearance = np.hypot(fr_x - 0.55, fr_y + 0.26) - section - soil_model.WIDTH / 2
    assert clearance[others_off].min() > -1e-3
    assert axle.max() > 0.2  # over the rock's flank: the support at the contact lets it climb


def test_a_rover_that_cannot_get_past_is_stuck_and_the_chain_goes_on(
        rover: FmuRunner, tmp_path: Path) -> None:
    # A wall of rocks taller than the axle across the whole way: the front wheels stop at it,
    # `stuck` says so, the command ends by its timeout and the next command (reverse 0.2 m)
    # backs the rover away: the run goes on.
    wall = [Rock(0.45, y, 0.05, 0.08, 0.3, z=0.15) for y in (-0.3, -0.15, 0.0, 0.15, 0.3)]
    terrain = str(write_terrain(tmp_path / "wall.terrain",
                                synthetic_terrain(size=4.0, cell=0.02, rocks=wall)))
    chain = [Command(0.05, 1.0, 0.0), Command(0.05, -0.2, 0.0)]
    out = rover.run({"terrain.file": terrain}, chain, 700.0, 0.1)
    assert out["stuck"][out["command"] == 0].max() == 1.0
    reversing = out["command"] == 1
    assert reversing.any() and out["command"][-1] == -1
    assert out["stuck"][reversing][-100:].max() == 0.0  # backing away is progress again
    assert out["x"][reversing][-1] < out["x"][reversing][0] - 0.15
    assert _longest_still_while_driving(out) <= 2


def test_a_wheel_on_a_rock_puts_the_rigid_chassis_on_its_diagonal(
        rover: FmuRunner, tmp_path: Path) -> None:
    # A 4 cm rock under the right wheels lifts the front right wheel far more than the soil
    # and legs can give (twist T = 4 w / sum c_i saturates): the chassis rests on the FR-RL
    # diagonal, each carrying about half the weight, and FL, RR unload (a rigid plate on three
    # supports at rectangle corners: W/2, W/2, 0).
    terrain = _terrain(tmp_path, Rock(0.55, -0.26, 0.06, 0.06, 0.04, z=0.0), "rock.terrain")
    out = rover.run({**ODOMETRY, "terrain.file": terrain}, STRAIGHT, 250.0, 0.1)
    loads = _loads(out)
    static = soil_model.WHEEL_LOAD
    k = int(np.argmax(loads[:, 1]))
    assert loads[k, 1] == pytest.approx(2 * static, rel=0.1)
    assert loads[k, 2] == pytest.approx(2 * static, rel=0.1)
    assert loads[k, 0] < 0.1 * static and loads[k, 3] < 0.1 * static
    np.testing.assert_allclose(loads[k].sum(), 4 * static, rtol=0.02)
    # the same rock under very compliant legs: the twist goes into the legs, loads stay equal
    soft = _loads(rover.run({**ODOMETRY, "terrain.file": terrain, "rover.leg_compliance": 1e3},
                            STRAIGHT, 250.0, 0.1))
    assert np.abs(soft[k] - static).max() < 0.05 * static


def test_loads_are_equal_on_flat_ground(rover: FmuRunner) -> None:
    loads = _loads(rover.run({}, STRAIGHT, 50.0, 0.1))
    np.testing.assert_allclose(loads, soil_model.WHEEL_LOAD, rtol=1e-9)


def _push_over_load_of_the_diagonal_partner() -> float:
    """Net push per unit load of the climbing wheel's diagonal partner, the one wheel left
    pushing when the chassis rests on its diagonal (W/2 each): full-slip shear of fresh soil
    without slip sinkage (the weakest it gets) minus its compaction resistance."""
    load = soil_model.MASS * soil_model.GRAVITY / 2
    sinkage = soil_model.static_sinkage(load)
    push = soil_model.strength(load, sinkage) * soil_model.janosi(
        soil_model.shear_length(sinkage) * 0.95) - soil_model.compaction(sinkage)
    return push / load


def test_stuck_means_no_way_on_not_a_slow_climb_or_a_pivot(
        rover: FmuRunner, tmp_path: Path) -> None:
    # Disc against an edge: a driven wheel whose contact is below its axle (contact angle
    # alpha < 90°) gets over when the push behind it reaches W tan(alpha - atan(m mu)); with
    # m mu = 0.95 * 0.6 the worst case alpha -> 90° needs P/W >= 1/(m mu) = 1.75, and the
    # diagonal partner alone pushes 2.6 W on the default soil. A face above the axle cannot be
    # climbed at any push, but a single rock leaves the rest of the rover free to pivot past.
    # `stuck` is "cannot progress": only a face across the whole way raises it. With heading
    # control (the default) the loop slows the left wheels against the pivot, so the climb and
    # the pivot are slow (the front right wheel slips at nearly 100 % for tens of seconds):
    # progress, for the slip rule to judge, not `stuck`.
    radius = soil_model.RADIUS
    assert _push_over_load_of_the_diagonal_partner() >= 1 / (0.95 * 0.6)
    example = {"size": 4.0, "cell": 0.02, "slope": math.radians(2), "roughness": 0.003,
               "seed": 11}  # campaigns/rock-detour.yaml's terrain and rock
    low = Rock(0.5, -0.26, 0.04, 0.04, 0.04, embed=0.01)
    assert 2 * low.c - low.embed < radius  # its top, so every contact, is below the axle
    tall = Rock(0.55, -0.26, 0.06, 0.06, 0.15, z=0.0)
    wall = [Rock(0.45, y, 0.05, 0.08, 0.3, z=0.15) for y in (-0.3, -0.15, 0.0, 0.15, 0.3)]
    for name, rocks, way_on in (("low", [low], True), ("tall", [tall], True),
                                ("wall", wall, False)):
        terrain = write_terrain(tmp_path / f"{name}.terrain",
                                synthetic_terrain(rocks=rocks, **example))
        out = rover.run({"terrain.file": str(terrain)}, STRAIGHT, 420.0, 0.1)
        fr_x = out["x"] + 0.20 * np.cos(out["yaw"]) + 0.26 * np.sin(out["yaw"])
        # a right wheel is held at the rock: above the 70 % slip the paper calls critical (at
        # the low rock the rear right one, on the chassis diagonal with the front left, while
        # the front right is lifted and, without a contact, slips nothing)
        assert out["wheel.slip"][:, [1, 3]].max() > 0.7, name
        if way_on:
            assert out["stuck"].max() == 0.0, name
            assert fr_x.max() > rocks[0].x + 0.1, name  # ... and then gets past the rock
        else:
            assert out["stuck"].max() == 1.0, name
            assert fr_x.max() < 0.45 - 0.05 - 0.10 + 0.002, name  # its rim at the face
        assert _longest_still_while_driving(out) <= 2, name  # never frozen


def _contact_changes(out: dict[str, np.ndarray]) -> np.ndarray:
    """Per wheel: how often it went from the soil onto a rock or back, over the samples where
    it carried load (a wheel on a rock makes no sinkage; a lifted one is neither)."""
    changes = []
    for i, wheel in enumerate(WHEELS):
        loaded = out[f"wheel.{wheel}.load"] > 1e-4  # N: a wheel carrying load
        on_rock = out["wheel.sinkage"][loaded, i] == 0.0
        changes.append(int(np.count_nonzero(np.diff(on_rock.astype(int)))))
    return np.array(changes)


@pytest.mark.parametrize("feedback", [1.0, 0.0])
@pytest.mark.parametrize("slope_deg", [0.0, 10.0])
def test_a_wheel_in_a_rut_takes_a_pebble_once_and_leaves_it_once(
        rover: FmuRunner, tmp_path: Path, feedback: float, slope_deg: float) -> None:
    # A 1 cm pebble in the right wheels' track. A wheel meets it where the soil would carry it
    # some depth below the surface: the front right wheel 1.4 mm (fresh soil), the rear right
    # one 1.9 mm (in the front wheel's rut). The rock holds a wheel while it holds it above that
    # depth, taken for a wheel on the rock from its load or share, the rut under it and the
    # depth it got on with (docs/rover-model.md, "Rocks"): onto the pebble once, off it once.
    # When the comparison was made at the rock's zero sinkage, a rim between the soil surface
    # and that depth was on the soil one step and on the rock the next: 26 changes for the
    # front right wheel and 34 (32 open loop) for the rear right one over this drive on level
    # ground, the loads and slips alternating with them. Downhill, a wheel carries more on the
    # soil than a level share and less on the rock: without the depth it got on with, the
    # front right wheel changes 6 times.
    terrain = str(write_terrain(tmp_path / "pebble.terrain", synthetic_terrain(
        size=4.0, cell=0.02, slope=math.radians(slope_deg),
        rocks=[Rock(0.35, -0.26, 0.01, 0.01, 0.01, embed=0.003)])))
    out = rover.run({"terrain.file": terrain, "controller.heading_feedback": feedback},
                    STRAIGHT, 300.0, 0.02)
    assert out["x"][-1] > 0.95  # the whole drive, over the pebble
    changes = _contact_changes(out)
    assert changes[[0, 2]].tolist() == [0, 0]  # the left wheels never touch it
    assert changes[[1, 3]].tolist() == [2, 2]  # onto the pebble once, off it once
