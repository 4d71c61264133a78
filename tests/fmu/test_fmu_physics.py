"""Plausibility of the rover model: each test is one physical statement (docs/rover-model.md)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import soil_model

from idefix_rules.commands import Command
from idefix_rules.fmu import FmuRunner, Rock, synthetic_terrain, write_terrain
from idefix_rules.fmu.variables import VARIABLES_BY_NAME

FL, FR, RL, RR = range(4)
STRAIGHT = [Command(0.05, 1.0, 0.0)]  # 200 s at 5 mm/s


def test_flat_straight_drive_slips_as_the_soil_predicts_and_covers_distance_times_one_minus_slip(
        rover: FmuRunner) -> None:
    out = rover.run({}, STRAIGHT, 210.0, 0.1)
    # strength(z) f(L s) = compaction(z) with the slip sinkage z (tests/fmu/soil_model.py):
    # 0.0118 for the default soil
    predicted = soil_model.driving_slip()
    # first pass (before the rear wheels reach the front wheels' ruts at about 83 s): within 2 %
    # (the model's slip sinkage follows the slip over the rim's travel; regularised shear law)
    assert out["wheel.slip"][500] == pytest.approx(np.full(4, predicted), rel=0.02)
    # once the rear wheels run in the front wheels' ruts (after 0.4 m, 80 s): the soil carries
    # them only below the rut's floor, with the remoulded cohesion, and compacts it from the
    # floor down; the four wheels share one slip, the fronts' net pull carrying the rears' net
    # drag (soil_model.two_axle_slip: 0.0157): within 2 %
    second = soil_model.two_axle_slip()
    assert out["wheel.slip"][1500] == pytest.approx(np.full(4, second), rel=0.02)
    driving = out["command"] == 0
    slip = float(out["wheel.slip"][driving].mean())
    assert predicted < slip < second
    # consistency: the odometry-ended drive covers the commanded metre times (1 - slip)
    assert out["x"][-1] == pytest.approx(1.0 * (1.0 - slip), rel=0.01)
    assert abs(out["y"][-1]) < 1e-9 and abs(out["yaw"][-1]) < 1e-9


@pytest.mark.parametrize(("offset", "heading"), [(0.002, 0.0), (0.005, 0.0), (0.007, 0.0),
                                                 (0.005, math.pi / 4), (0.005, math.pi / 2)])
def test_a_rear_wheel_finds_the_whole_rut_wherever_its_edge_falls_in_a_cell(
        rover: FmuRunner, tmp_path: Path, offset: float, heading: float) -> None:
    # On a terrain file the rut grid is fixed to the terrain, so starting the drive a few
    # millimetres to the side puts the ruts' edges inside 1 cm cells. A partly pressed cell
    # holds its mean depth; the patch reads the pressed part's depth on the side of the edge
    # line reconstructed from the neighbours (docs/rover-model.md, "Ruts"), so the rear wheels
    # find the front wheels' ruts as deep and as wide as they were pressed and the two axles
    # slip as soil_model.two_axle_slip says (0.0157), as with the edges on the cells' borders.
    # Read as the mean over the cell instead, the rut's edge cells are shallower under the
    # wheel and the slip falls to 0.0147 at 5 mm. Driven at 45° and 90° to the grid the edges
    # cross the cells obliquely or along y: an edge line mirrored the wrong way across x
    # (a sign of the normal) errs by 4.7 % at 45° and 12.8 % at 90°.
    flat = write_terrain(tmp_path / "flat.terrain", synthetic_terrain(size=4.0, cell=0.02))
    across = (-math.sin(heading) * offset, math.cos(heading) * offset)
    out = rover.run({"terrain.file": str(flat), "initial.x": across[0], "initial.y": across[1],
                     "initial.yaw": heading}, STRAIGHT, 210.0, 0.1)
    assert out["wheel.slip"][1500] == pytest.approx(np.full(4, soil_model.two_axle_slip()),
                                                    rel=0.02)


def test_point_turn_ends_near_the_skid_steering_yaw(rover: FmuRunner) -> None:
    # Isotropic shear on four wheels at (±a, ±b) alone would turn the body at b²/(a²+b²) = 0.63
    # of the commanded yaw rate; lateral bulldozing and compaction resist the turn too: the yaw
    # moment balance gives 0.54 on fresh soil, with the slip sinkage of the rims' slip 1 - eta
    # (docs/rover-model.md, "Skid steering"). Open loop on wheel odometry: the lag shows as
    # heading error (the closed loop corrects it).
    commanded = math.pi / 2
    out = rover.run({"controller.heading_feedback": 0.0}, [Command(0.05, 0.0, commanded)],
                    100.0, 0.1)
    efficiency = out["yaw"][-1] / commanded
    assert efficiency == pytest.approx(soil_model.point_turn_efficiency(), rel=0.02)
    assert efficiency < 0.26**2 / (0.20**2 + 0.26**2)
    assert math.hypot(out["x"][-1], out["y"][-1]) < 1e-3  # turns on the spot
    turning = out["command"] == 0
    assert np.all(np.abs(out["wheel.slip_angle"][turning][10:]) > 0.3)  # lateral skid


def test_drive_across_a_slope_crabs_as_the_lateral_shear_and_bulldozing_balance_says(
        rover: FmuRunner, tmp_path: Path) -> None:
    # Across a 10° slope the in-plane gravity m g sin(10°) pulls the rover downhill (-y). The
    # lateral shear of the patches and the soil's passive (bulldozing) pressure beside each
    # wheel, L z c K_c bounded by the wheel load, both build up with the wheels' sideways
    # displacement (docs/rover-model.md, "Lateral bulldozing"): the rover crabs downhill at the
    # small angle where they carry the weight, about 3.6 cm over the metre with the heading held.
    slope = math.radians(10)
    z = soil_model.static_sinkage(soil_model.WHEEL_LOAD)
    lateral = 4 * min(soil_model.bulldozing(z), soil_model.WHEEL_LOAD * math.cos(slope))
    assert lateral > 25.0 * 0.0057 * math.sin(slope)
    terrain = write_terrain(tmp_path / "slope.terrain", synthetic_terrain(
        size=5.0, cell=0.05, slope=slope, slope_direction=-math.pi / 2))
    out = rover.run({"terrain.file": str(terrain)}, STRAIGHT, 210.0, 0.1)
    assert out["x"][-1] > 0.95
    # fresh soil for the first 0.4 m (the wheelbase), then the rear wheels in the ruts of the
    # front ones, where they hold less: 2.9 and 4.3 cm per metre
    expected = soil_model.side_slope_crab(slope) * 0.4 + soil_model.side_slope_crab(
        slope, ruts=True) * (out["x"][-1] - 0.4)
    assert -out["y"][-1] == pytest.approx(expected, rel=0.1)
    assert -out["y"][-1] < 0.05
    # left side up; the loaded downhill wheels sink deeper and add a little roll
    assert out["roll"][-1] == pytest.approx(slope, abs=math.radians(0.5))
    loads = out["wheel.FR.load"][1000], out["wheel.FL.load"][1000]
    assert loads[0] > 1.1 * loads[1]  # the downhill (right) wheels carry more


def test_rock_under_the_right_wheels_rolls_the_rover_and_spikes_their_slip(
        rover: FmuRunner, tmp_path: Path) -> None:
    rock = Rock(x=0.6, y=-0.26, a=0.06, b=0.06, c=0.04)
    terrain = write_terrain(tmp_path / "rock.terrain",
                            synthetic_terrain(size=4.0, cell=0.02, rocks=[rock]))
    flat = rover.run({}, STRAIGHT, 210.0, 0.1)
    out = rover.run({"terrain.file": str(terrain)}, STRAIGHT, 210.0, 0.1)
    assert out["roll"].min() < math.radians(-3)  # right side up: negative roll
    assert out["roll"].max() < math.radians(0.1)
    flat_slip = float(flat["wheel.slip"][1000, FR])
    crossing = slice(50, 2000)  # after the start-up slip of the first second
    assert out["wheel.slip"][crossing, FR].max() > 3 * flat_slip
    assert out["wheel.slip"][crossing, FR].max() > out["wheel.slip"][crossing, FL].max()
    assert out["z"].max() > flat["z"].max() + 0.01


def test_softer_soil_sinks_and_slips_more(rover: FmuRunner) -> None:
    firm = rover.run({}, STRAIGHT, 100.0, 0.1)
    soft = rover.run({"soil.k_phi": 200e3, "soil.cohesion": 60.0}, STRAIGHT, 100.0, 0.1)
    assert soft["wheel.sinkage"][500].min() > 1.5 * firm["wheel.sinkage"][500].max()
    assert soft["wheel.slip"][500].min() > 1.5 * firm["wheel.slip"][500].max()
    assert soft["x"][-1] < firm["x"][-1]


def test_rear_wheels_in_the_front_wheels_ruts_differ(rover: FmuRunner) -> None:
    # the rear wheels reach the front wheels' first ruts after 0.4 m (about 83 s)
    out = rover.run({}, STRAIGHT, 160.0, 0.1)
    sinkage, current = out["wheel.sinkage"][1500], out["wheel.current"][1500]
    assert sinkage[RL] > 1.1 * sinkage[FL] and sinkage[RR] > 1.1 * sinkage[FR]
    assert current[RL] != pytest.approx(current[FL], rel=1e-3)
    early = out["wheel.sinkage"][500]
    assert early[RL] == pytest.approx(early[FL], rel=1e-9)  # not yet in a rut


def test_energy_grows_with_distance_and_more_with_turning(rover: FmuRunner) -> None:
    one = rover.run({}, [Command(0.05, 0.5, 0.0)], 300.0, 0.1)["energy"][-1]
    two = rover.run({}, [Command(0.05, 1.0, 0.0)], 300.0, 0.1)["energy"][-1]
    assert two > 1.8 * one
    # same wheel travel on the outer side, but turning: more charge per second of driving
    arc = rover.run({}, [Command(0.05, 0.5, 0.6)], 300.0, 0.1)
    straight = rover.run({}, [Command(0.05, 0.5 + 0.26 * 0.6, 0.0)], 300.0, 0.1)
    assert arc["energy"][-1] > 1.1 * straight["energy"][-1]


def test_nothing_goes_nan_on_rough_rocky_terrain(rover: FmuRunner, tmp_path: Path) -> None:
    rocks = [Rock(x, y, 0.04 + 0.02 * (k % 3), 0.05, 0.03 + 0.01 * (k % 4))
             for k, (x, y) in enumerate([(0.3, 0.2), (0.5, -0.25), (0.8, 0.0), (0.2, -0.3),
                                         (1.0, 0.3), (0.6, 0.26), (0.1, 0.5)])]
    rough = write_terrain(tmp_path / "rough.terrain", synthetic_terrain(
        size=4.0, cell=0.02, roughness=0.02, correlation_length=0.05, seed=7, slope=0.2,
        slope_direction=2.0, rocks=rocks))
    chain = [Command(0.05, 0.6, 0.5), Command(0.08, 0.0, -1.2), Command(0.05, -0.3, 0.4),
             Command(0.05, 0.5, 0.0)]
    out = rover.run({"terrain.file": str(rough), "soil.cohesion": 50.0}, chain, 500.0, 0.1)
    for name, values in out.items():
        assert np.all(np.isfinite(values)), name


def test_halving_the_internal_step_changes_the_final_pose_by_less_than_2_mm(
        rover: FmuRunner, tmp_path: Path) -> None:
    # Rough ground with a rock, an arc, a point turn and an arc (docs/rover-model.md, "Step
    # size and convergence"): the motion is regular (no stall), so the final pose converges.
    terrain = write_terrain(tmp_path / "conv.terrain", synthetic_terrain(
        size=4.0, cell=0.02, roughness=0.005, seed=3, rocks=[Rock(0.4, -0.2, 0.05, 0.05, 0.03)]))
    chain = [Command(0.05, 0.5, 0.4), Command(0.05, 0.0, -1.0), Command(0.04, 0.6, -0.3)]
    poses = []
    for step in (0.05, 0.025):
        out = rover.run({"terrain.file": str(terrain), "solver.step": step}, chain, 450.0, 0.1)
        assert out["stuck"].max() == 0.0
        poses.append((out["x"][-1], out["y"][-1], out["yaw"][-1]))
    (x1, y1, yaw1), (x2, y2, yaw2) = poses
    assert math.hypot(x1 - x2, y1 - y2) < 0.002
    assert abs(yaw1 - yaw2) < 0.002


def test_rock_taller_than_the_wheel_blocks_and_reports_stuck(
        rover: FmuRunner, tmp_path: Path) -> None:
    wall = [Rock(0.45, y, 0.05, 0.08, 0.3, z=0.15) for y in (-0.3, -0.15, 0.0, 0.15, 0.3)]
    terrain = write_terrain(tmp_path / "wall.terrain",
                            synthetic_terrain(size=4.0, cell=0.02, rocks=wall))
    out = rover.run({"terrain.file": str(terrain)}, STRAIGHT, 210.0, 0.1)
    # front wheel rims stop at the rock face: x + 0.20 + 0.10 <= 0.45 - 0.05
    assert out["x"].max() < 0.45 - 0.05 - 0.30 + 0.002
    assert out["stuck"].max() == 1.0
    assert out["wheel.slip"][1500].min() > 0.9


def test_a_stalled_motor_ends_the_command_by_timeout(rover: FmuRunner) -> None:
    out = rover.run({"motor.max_torque": 1e-6, "controller.timeout_factor": 1.5}, STRAIGHT,
                    400.0, 0.1)
    finished = int(np.argmax(out["command"] < 0)) * 0.1
    ramp = 0.05 / 0.015  # the trapezoidal profile's extra time (controller.wheel_acceleration)
    assert finished == pytest.approx(1.5 * (200.0 + ramp), abs=0.2)
    assert out["x"][-1] < 0.05


def test_reversing_over_its_own_track_is_a_second_pass_whatever_the_track_age(
        rover: FmuRunner) -> None:
    # 0.1 m or 0.3 m forward and back (shorter than the 0.4 m wheelbase: each wheel meets only
    # its own track). Back over it, the soil is a rut the wheel left: multi-pass sinkage
    # z_p + multipass_factor * z (docs/rover-model.md, "Ruts"), 1.3 x the first pass with the
    # defaults, whether the marks are 20 s or 60 s old: compared at the same distance into the
    # reverse (about 4.5 cm, 11 s after it began), where the marks were made alike.
    mid_reverse = []
    for length in (0.1, 0.3):
        out = rover.run({}, [Command(0.05, length, 0.0), Command(0.05, -length, 0.0)],
                        2.0 * (length / 0.005 + 4.0) + 10.0, 0.1)
        forward = np.flatnonzero(out["command"] == 0)
        back = np.flatnonzero(out["command"] == 1)
        first = out["wheel.sinkage"][forward[len(forward) // 2]]
        second = out["wheel.sinkage"][back[0] + 110]
        assert np.all(second > 1.25 * first) and np.all(second < 1.4 * first)
        mid_reverse.append(second)
    np.testing.assert_allclose(mid_reverse[0], mid_reverse[1], rtol=1e-3)


def _janosi(j: float, K: float = 0.012) -> float:
    return soil_model.janosi(j, K)


def _downhill_skid(slope: float) -> float:
    """|slip| at which the four braking wheels and their compaction resistance carry the
    downhill weight: sum F_max f(L |s|) + R_c = m g sin(slope), loads with the load transfer."""
    from scipy.optimize import brentq

    m, g, half_wheelbase, cog = 25.0, 0.0057, 0.2, 0.25
    gz, gx = g * math.cos(slope), g * math.sin(slope)
    wheels = [soil_model.wheel_at_rest(m * gz / 4 + side * m * gx * cog / (4 * half_wheelbase))
              for side in (1, 1, -1, -1)]
    return brentq(lambda s: sum(cap * _janosi(length * s) + rc for length, cap, rc in wheels)
                  - m * gx, 1e-9, 1.0)


@pytest.mark.parametrize("degrees", [15, 25])
def test_driving_downhill_skids_at_the_slip_the_soil_can_brake(
        rover: FmuRunner, tmp_path: Path, degrees: int) -> None:
    # Downhill the wheels brake: the body runs ahead of the rims (negative slip) until the
    # mobilised shear carries the weight along the slope. The balance slip depends on slope and
    # soil only, so both wheel rates give the same slip, and the speed is rim / (1 - |s|).
    slope = math.radians(degrees)
    terrain = write_terrain(tmp_path / "downhill.terrain", synthetic_terrain(
        size=6.0, cell=0.05, slope=slope, slope_direction=0.0))  # downhill is +x
    skid = _downhill_skid(slope)
    for rate in (0.05, 0.02):
        out = rover.run({"terrain.file": str(terrain)}, [Command(rate, 0.5, 0.0)], 12.0, 0.1)
        assert out["wheel.slip"][100] == pytest.approx(np.full(4, -skid), abs=0.01)
        speed = (out["x"][101] - out["x"][99]) / 0.2 / math.cos(slope)  # along the slope
        assert speed == pytest.approx(rate * 0.1 / (1 - skid), rel=0.02)
        assert out["stuck"].max() == 0.0


def test_a_slope_steeper_than_the_soil_holds_is_an_accelerating_slide_flagged_stuck(
        rover: FmuRunner, tmp_path: Path) -> None:
    # On cohesionless soil the full-skid strength W tan(phi) f(L) of the four wheels is below
    # m g sin(35°): no speed balances the weight, so the rover accelerates downhill, motors
    # holding or not. With the default cohesion the same slope is held: in milli-g the patch's
    # cohesion b L c alone is several wheel loads.
    slope = math.radians(35)
    m, g = 25.0, 0.0057

    def strength(cohesion: float) -> float:
        loads = [m * g * math.cos(slope) / 4 + side * m * g * math.sin(slope) * 0.25 / (4 * 0.2)
                 for side in (1, 1, -1, -1)]
        wheels = [soil_model.wheel_at_rest(load, cohesion) for load in loads]
        return sum(cap * _janosi(length) for length, cap, _ in wheels)

    assert strength(0.0) < m * g * math.sin(slope) < strength(250.0)
    terrain = write_terrain(tmp_path / "steep.terrain", synthetic_terrain(
        size=6.0, cell=0.05, slope=slope, slope_direction=0.0))
    for chain in ([], [Command(0.05, 0.5, 0.0)]):
        out = rover.run({"terrain.file": str(terrain), "soil.cohesion": 0.0}, chain, 20.0, 0.1)
        assert out["x"][-1] < 0.3
        speed = np.diff(out["x"][::25]) / 2.5
        assert np.all(np.diff(speed) > 0)  # accelerating
        assert out["stuck"][-1] == 1.0
    held = rover.run({"terrain.file": str(terrain)}, [], 20.0, 0.1)
    assert abs(held["x"][-1]) < 1e-6 and held["stuck"].max() == 0.0


def _slide_acceleration(out: dict[str, np.ndarray], start: float, end: float) -> float:
    """Acceleration along the path over [start, end] s: the second coefficient of a quadratic
    least-squares fit of the distance slid (x and z of the body, the path's own length)."""
    distance = np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(out["x"]), np.diff(out["z"])))])
    window = (out["t"] >= start) & (out["t"] <= end)
    return float(2.0 * np.polyfit(out["t"][window], distance[window], 2)[0])


def _newton_slide_acceleration(out: dict[str, np.ndarray], slope: float, sample: int) -> float:
    """Newton's second law along the slope for held wheels on cohesionless soil: every wheel
    skids fully (|s| = 1: its shear displacement is its whole patch, j = L) and ploughs its
    compaction resistance, so m a = m g sin(slope) - sum (W_i tan(phi) f(L_i) + R_c,i), with
    the loads W_i and sinkages z_i the run reports (the statics have their own tests) and the
    soil's equations written again in `soil_model`."""
    m, g = soil_model.MASS, soil_model.GRAVITY
    k = soil_model.modulus(0.0)
    resistance = 0.0
    for i, wheel in enumerate(("FL", "FR", "RL", "RR")):
        load, sinkage = out[f"wheel.{wheel}.load"][sample], out["wheel.sinkage"][sample][i]
        shear = load * math.tan(soil_model.FRICTION) * _janosi(soil_model.shear_length(sinkage))
        resistance += shear + soil_model.WIDTH * k * sinkage ** 2 / 2
    return (m * g * math.sin(slope) - resistance) / m


def test_the_slide_on_a_slope_the_soil_cannot_hold_accelerates_as_newtons_law_gives(
        rover: FmuRunner, tmp_path: Path) -> None:
    # Held wheels on cohesionless soil at 35°: the wheels' full-skid shear and compaction
    # resistance carry 96 % of the downhill weight, so the slide's acceleration (about
    # 0.14 mm/s²) is the small difference of two large forces, and 2 % of it is 0.08 % of the
    # weight along the slope. The regularised shear displacement j = L v / (v + eps) is short
    # of L while the speed is a few eps: with eps = 1 µm/s that is over within a second, with
    # the default 10 µm/s the slide starts faster (5 % at 5 s) and reaches the same law later.
    slope = math.radians(35)
    terrain = write_terrain(tmp_path / "steep.terrain", synthetic_terrain(
        size=6.0, cell=0.05, slope=slope, slope_direction=0.0))
    soil = {"terrain.file": str(terrain), "soil.cohesion": 0.0}
    fine = rover.run({**soil, "solver.velocity_epsilon": 1e-6}, [], 20.0, 0.1)
    expected = _newton_slide_acceleration(fine, slope, 150)
    assert 0.12e-3 < expected < 0.16e-3
    assert _slide_acceleration(fine, 5.0, 20.0) == pytest.approx(expected, rel=0.02)
    default = rover.run(soil, [], 60.0, 0.1)
    assert _newton_slide_acceleration(default, slope, 500) == pytest.approx(expected, rel=1e-6)
    assert _slide_acceleration(default, 2.0, 8.0) > 1.03 * expected
    assert _slide_acceleration(default, 45.0, 60.0) == pytest.approx(expected, rel=0.02)


def _flat_with(tmp_path: Path, rocks: list[Rock], name: str = "rocks.terrain") -> Path:
    return write_terrain(tmp_path / name, synthetic_terrain(size=4.0, cell=0.02, rocks=rocks))


def test_a_thin_tall_pebble_under_the_wheel_edge_lifts_the_wheel(
        rover: FmuRunner, tmp_path: Path) -> None:
    # A 5 cm tall pebble of 6 mm radius, 15 mm off the right wheels' centre line (inside their
    # 60 mm width): the wheel must roll over it, lifting its corner of the body plane by the
    # pebble's height, i.e. the body centre by a quarter of it.
    flat = rover.run({}, STRAIGHT, 210.0, 0.1)
    pebble = _flat_with(tmp_path, [Rock(0.6, -0.26 - 0.015, 0.006, 0.006, 0.05, z=0.0)])
    out = rover.run({"terrain.file": str(pebble)}, STRAIGHT, 210.0, 0.1)
    assert out["z"].max() - flat["z"].max() > 0.9 * 0.05 / 4
    assert out["roll"].min() < -0.9 * math.atan(0.05 / (2 * 0.26)) / 2


PEBBLES = [Rock(0.35, -0.30, 0.01, 0.01, 0.01, embed=0.003),
           Rock(0.60, 0.22, 0.01, 0.01, 0.01, embed=0.003),
           Rock(0.75, -0.10, 0.012, 0.012, 0.012, embed=0.004),
           Rock(0.55, 0.42, 0.04, 0.04, 0.04, embed=0.01, level="L2")]


@pytest.mark.parametrize("cohesion", [136.0, 250.0])
def test_a_command_starting_on_a_pebble_accelerates_the_body_with_the_wheel_ramp(
        rover: FmuRunner, tmp_path: Path, cohesion: float) -> None:
    # campaigns/pebble-field.yaml's two-legs chain in one of its drawn worlds (run 17 of 200):
    # the second leg starts with the front left wheel on a pebble and the front right one
    # lifted (the chassis on a diagonal), where the balance search fails on the first small
    # wheel rates. The rover then moves as Newton's second law gives with the forces at play
    # (docs/rover-model.md, "Quasi-static motion"): the body stays with its rims and goes up
    # their ramp, controller.wheel_acceleration times the wheel radius (1.5 mm/s^2), no faster
    # and without stalling. Following the failed search's last iterate instead kicked the body
    # to twice its rims' speed (slip -1) and 6.5 mm/s^2, above the default rulebook's 3 mm/s^2
    # limit; keeping the previous velocity, or turning the implicit step's sign round, leaves
    # the body behind or ahead of its rims (slip -0.36 to -1).
    terrain = write_terrain(tmp_path / "pebbles.terrain", synthetic_terrain(
        size=4.0, cell=0.02, slope=math.radians(1.0), slope_direction=math.radians(90.0),
        roughness=0.002, seed=7, rocks=PEBBLES))
    two_legs = [Command(0.05, 0.4, 0.0), Command(0.05, 0.4, 0.0)]
    out = rover.run({"terrain.file": str(terrain), "soil.cohesion": cohesion,
                     "soil.friction_angle": 0.5774, "initial.x": 0.0096,
                     "initial.y": -0.01656, "initial.yaw": -0.00671}, two_legs, 200.0, 0.05)
    t = out["t"]
    speed = np.hypot(np.gradient(out["x"], t), np.gradient(out["y"], t))
    second = int(np.argmax(out["command"] == 1))
    ramping = slice(second + 2, second + 60)  # central differences clear of the first leg
    # on the pebble (no sinkage into soil, a load) and lifted (no load)
    assert out["wheel.sinkage"][second, FL] == 0.0 and out["wheel.FL.load"][second] > 0.0
    assert out["wheel.FR.load"][second] == 0.0
    ramp = float(VARIABLES_BY_NAME["controller.wheel_acceleration"].start) * float(
        VARIABLES_BY_NAME["rover.wheel_radius"].start)
    acceleration = np.gradient(speed, t)[ramping]
    assert 0.8 * ramp < acceleration.min() and acceleration.max() < 1.1 * ramp
    # the body never runs far ahead of its rims once they turn (at the leg's first sample the
    # rims have not started, 1e-5 rad/s, and the body still creeps from the first leg: a slip
    # reading of 0/0, -0.08 to -0.3 depending on the loads the first leg left)
    turning = slice(second + 1, second + 60)  # the rest of the leg's first 3 s, 0.05 s steps
    assert (np.abs(out["wheel.rate"][turning]) > 1e-4).all()
    assert out["wheel.slip"][turning].min() > -0.15


def test_every_rock_near_a_wheel_counts_however_many(rover: FmuRunner, tmp_path: Path) -> None:
    # 40 low pebbles around the right front wheel's path, then one 4 cm rock last in the file:
    # the last one lifts the wheel as if it were alone.
    pebbles = [Rock(0.5 + 0.01 * (k % 10), -0.29 + 0.015 * (k // 10), 0.004, 0.004, 0.005, z=0.0)
               for k in range(40)]
    tall = Rock(0.56, -0.26, 0.02, 0.02, 0.04, z=0.0)
    alone = rover.run({"terrain.file": str(_flat_with(tmp_path, [tall], "alone.terrain"))},
                      STRAIGHT, 210.0, 0.1)
    crowded = rover.run({"terrain.file": str(_flat_with(tmp_path, [*pebbles, tall]))},
                        STRAIGHT, 210.0, 0.1)
    assert crowded["z"].max() == pytest.approx(alone["z"].max(), abs=2e-4)
    assert alone["z"].max() > rover.run({}, STRAIGHT, 210.0, 0.1)["z"].max() + 0.009


def _wall_contact_angle(height: float, half_thickness: float, sinkage: float) -> float:
    """Contact angle (from the vertical) at which a wheel of radius 0.1 m, its rim `sinkage`
    into the soil, first touches a thin ellipsoidal wall: brute-force envelope of the disc."""
    r = 0.1
    d = np.linspace(-r, r, 40001)
    lift = np.sqrt(r * r - d * d)
    lo, hi = -r - half_thickness, 0.0  # wheel centre relative to the wall
    for _ in range(36):
        centre = 0.5 * (lo + hi)
        u = (centre + d) / half_thickness
        top = np.where(np.abs(u) < 1, height * np.sqrt(np.clip(1 - u * u, 0, None)), -1.0)
        if (top + lift).max() > r - sinkage:
            hi = centre
        else:
            lo = centre
    return math.asin(d[int(np.argmax(top + lift))] / r)


def _largest_push_over_weight(cohesion: float, dug_in: bool = True) -> tuple[float, float]:
    """Largest net push (thrust minus compaction) of a driven soil wheel over its load, over
    all slips, and its sinkage at full slip (docs/rover-model.md, "Soil"). `dug_in`: with the
    steady slip sinkage; otherwise at the static sinkage, as on fresh soil before the slip has
    dug the wheel in (the excavation builds up over one patch length of rim travel)."""
    load = soil_model.WHEEL_LOAD
    z0 = soil_model.static_sinkage(load, cohesion)
    best, sinkage = 0.0, z0
    for s in np.linspace(0.01, 1.0, 100):
        z = soil_model.slip_sinkage(z0, s) if dug_in else z0
        push = (soil_model.strength(load, z, cohesion)
                * _janosi(soil_model.shear_length(z) * s) - soil_model.compaction(z, cohesion))
        best, sinkage = max(best, push / load), soil_model.slip_sinkage(z0, s)
    return best, sinkage


def _climb_limit(mu_m: float, push: float) -> float:
    """Largest contact angle a the front wheels climb: P >= W_f tan(a - atan mu_m), with the
    rear wheels' push P = push W_r and the loads of a chassis on its four wheels with the front
    supports at their contacts, r sin a ahead of the hubs (docs/rover-model.md, "Loads"):
    W_r / W_f = (l + r sin a) / l (l the half wheelbase; moments about the centre of gravity)."""
    lo, hi = math.atan(mu_m), math.pi / 2
    for _ in range(60):
        a = 0.5 * (lo + hi)
        rear_over_front = 1 + soil_model.RADIUS * math.sin(a) / soil_model.HALF_WHEELBASE
        lo, hi = (a, hi) if math.tan(a - math.atan(mu_m)) <= push * rear_over_front else (lo, a)
    rear_over_front = 1 + soil_model.RADIUS / soil_model.HALF_WHEELBASE
    if math.tan(math.pi / 2 - math.atan(mu_m)) <= push * rear_over_front:
        return math.atan(mu_m) + math.atan(push * rear_over_front)  # beyond 90°: any wall
    return lo


@pytest.mark.parametrize("cohesion", [5.0, 250.0])
def test_a_step_is_climbed_while_the_push_lifts_the_wheel_over_its_edge(
        rover: FmuRunner, tmp_path: Path, cohesion: float) -> None:
    # Disc against a rigid edge at contact angle a (from the vertical), friction mobilised to
    # mu_m = 0.95 mu (rock.contact_length / rock.shear_K): the front wheels climb iff the rear
    # wheels' push P satisfies P >= W_f tan(a - atan mu_m). The walls' contacts are r sin a
    # ahead of the front hubs, which moves load to the rear: W_r / W_f = (l + r sin a) / l, so
    # with P = (P/W) W_r the limit a* solves tan(a* - atan mu_m) = (P/W) (1 + r sin a* / l).
    # P depends on how far the slip has dug the pushing wheels in: a*(dug in) <= a* <= a*(fresh
    # soil). Thin walls across both front wheels 5° of contact angle below the first and 10°
    # above the second decide it (the estimate takes the loads at the first contact: as the
    # front wheels rise, load moves to the pushing rear wheels, about 10 % each way, which
    # carries the rover up about 5° further).
    # Weak soil (c = 5 Pa): P/W = 0.14 dug in, 0.56 fresh: a* between 41° and 69°. Default
    # soil (P/W = 8.5): a* beyond 90°: a thin wall's rounded top reaches 90° only at the axle
    # height, so a wall just below the axle is climbed, and a rock whose face stands above the
    # axle (its top surface there is above the wheel centre: a = 90°, no push lifts the wheel)
    # stops the rover.
    push, sinkage = _largest_push_over_weight(cohesion)
    fresh, _ = _largest_push_over_weight(cohesion, dug_in=False)
    mu_m = 0.6 * (1 - 0.001 / 0.02 * (1 - math.exp(-20)))
    critical = _climb_limit(mu_m, push)  # wheels dug in by their slip
    highest = _climb_limit(mu_m, fresh)  # on fresh soil, before digging in
    heights = []
    for target, rim_depth in ((critical - math.radians(5), sinkage),
                              (highest + math.radians(10),
                               soil_model.static_sinkage(soil_model.WHEEL_LOAD, cohesion))):
        lo, hi = 0.001, 0.1
        for _ in range(16):
            h = 0.5 * (lo + hi)
            lo, hi = (lo, h) if _wall_contact_angle(h, 0.005, rim_depth) > target else (h, hi)
        heights.append(h)
    walls = [Rock(0.35, 0.0, 0.005, 0.5, heights[0], z=0.0)]
    if highest + math.radians(10) < math.pi / 2:
        walls.append(Rock(0.35, 0.0, 0.005, 0.5, heights[1], z=0.0))
    else:  # a face above the axle: a block resting on the ground, its rim 12.5 cm high
        walls.append(Rock(0.35, 0.0, 0.02, 0.5, 0.125, z=0.125))
    for wall_rock, climbs in zip(walls, (True, False), strict=True):
        height = wall_rock.z + wall_rock.c
        wall = _flat_with(tmp_path, [wall_rock], f"wall{height:.4f}.terrain")
        out = rover.run({"terrain.file": str(wall), "soil.cohesion": cohesion},
                        [Command(0.05, 0.5, 0.0)], 150.0, 0.1)
        assert bool(out["x"][-1] > 0.3) is climbs, height
        if not climbs:
            assert out["stuck"].max() == 1.0
