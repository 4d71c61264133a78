"""Soil physics of the rover model against the documented equations, re-derived independently
in tests/fmu/soil_model.py (docs/rover-model.md, "Soil" and "Model validation")."""

from __future__ import annotations

import math
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
import soil_model

from idefix_rules.commands import Command
from idefix_rules.fmu import FmuRunner, source_dir, synthetic_terrain, write_terrain

STRAIGHT = [Command(0.05, 1.0, 0.0)]
FIRST_PASS = 500  # 50 s: steady, before the rear wheels reach the front wheels' ruts (83 s)


@pytest.mark.parametrize("cohesion", [5.0, 50.0, 250.0])
def test_straight_slip_and_sinkage_follow_the_soil_and_grow_as_it_weakens(
        rover: FmuRunner, cohesion: float) -> None:
    # Reece's form ties the soil's stiffness to its cohesion: weaker regolith is softer too, so
    # the wheels sink deeper and slip more (13 % at 5 Pa, 3.3 % at 50 Pa, 1.2 % at 250 Pa).
    out = rover.run({"soil.cohesion": cohesion}, STRAIGHT, 60.0, 0.1)
    slip = soil_model.driving_slip(cohesion=cohesion)
    static = soil_model.static_sinkage(soil_model.WHEEL_LOAD, cohesion)
    assert out["wheel.slip"][FIRST_PASS] == pytest.approx(np.full(4, slip), rel=0.03)
    assert out["wheel.sinkage"][FIRST_PASS] == pytest.approx(
        np.full(4, soil_model.slip_sinkage(static, slip)), rel=0.02)


def test_weaker_regolith_slips_more(rover: FmuRunner) -> None:
    slips = [float(rover.run({"soil.cohesion": c}, STRAIGHT, 60.0, 0.1)["wheel.slip"][
        FIRST_PASS, 0]) for c in (5.0, 50.0, 250.0, 500.0)]
    assert slips == sorted(slips, reverse=True) and slips[0] > 5 * slips[-1]


def test_firm_soil_keeps_its_traction_through_the_grousers(
        rover: FmuRunner, tmp_path: Path) -> None:
    # 100 x k_phi: the static sinkage (0.34 mm) gives a patch of 8 mm, shorter than the
    # grousers' floor sqrt(2 r h_g) = 14 mm, over which the shear displacement then builds up
    # (the strength stays that of the pressed patch). Up a 15° slope the rover climbs at the
    # slip where the wheels' net pull carries m g sin(15°), instead of sliding back.
    firm = 100 * soil_model.K_PHI
    static = soil_model.static_sinkage(soil_model.WHEEL_LOAD, k_phi=firm)
    assert math.sqrt(2 * soil_model.RADIUS * static) < soil_model.shear_length(static)
    slope = math.radians(15)
    uphill = write_terrain(tmp_path / "uphill.terrain", synthetic_terrain(
        size=6.0, cell=0.05, slope=slope, slope_direction=math.pi))  # uphill towards +x
    for k_phi in (soil_model.K_PHI, firm):
        out = rover.run({"terrain.file": str(uphill), "soil.k_phi": k_phi}, STRAIGHT, 250.0, 0.1)
        slip = soil_model.uphill_slip(slope, k_phi=k_phi)
        assert out["wheel.slip"][FIRST_PASS] == pytest.approx(np.full(4, slip), rel=0.03)
        assert out["x"][-1] > 0.75 and out["stuck"].max() == 0.0  # climbs, no slide back


def test_stepped_wheel_rates_settle_at_the_same_slip_as_ramped_ones(rover: FmuRunner) -> None:
    # Slip sinkage has two balances on weak soil (the driving one at 13 % and a runaway one
    # near full slip). The excavation builds up over the rim's travel, so the start-up slip of
    # stepped rates (over 90 % for a fraction of a second) does not dig the wheels in.
    weak = {"soil.cohesion": 5.0}
    slip = soil_model.driving_slip(cohesion=5.0)
    ramped = rover.run(weak, STRAIGHT, 60.0, 0.1)
    stepped = rover.run({**weak, "controller.wheel_acceleration": 0.0}, STRAIGHT, 60.0, 0.1)
    assert stepped["wheel.slip"][1:20].max() > 0.5  # the start-up spike is there
    for out in (ramped, stepped):
        assert out["wheel.slip"][FIRST_PASS] == pytest.approx(np.full(4, slip), rel=0.03)


def test_slip_sinkage_builds_up_over_the_rims_travel(rover: FmuRunner) -> None:
    # After a rate step the excavation approaches its steady value as 1 - exp(-travel / L):
    # within the first 0.2 s (1 mm of rim travel) the sinkage has barely grown.
    out = rover.run({"soil.cohesion": 5.0, "controller.wheel_acceleration": 0.0}, STRAIGHT,
                    30.0, 0.1)
    static = soil_model.static_sinkage(soil_model.WHEEL_LOAD, 5.0)
    steady = soil_model.slip_sinkage(static, soil_model.driving_slip(cohesion=5.0))
    early = float(out["wheel.sinkage"][2, 0])
    assert early - static < 0.2 * (soil_model.slip_sinkage(static, 0.9) - static)
    assert float(out["wheel.sinkage"][250, 0]) == pytest.approx(steady, rel=0.02)


def test_sinkage_is_bounded_by_the_compressible_layer(rover: FmuRunner) -> None:
    # A long point turn on weak soil digs the wheels in (slip sinkage, then multi-pass over
    # their own tracks: 18.6 mm unbounded); the sinkage stops at soil.max_sinkage.
    bound = 0.004
    out = rover.run({"soil.max_sinkage": bound, "soil.cohesion": 20.0},
                    [Command(0.05, 0.0, 4 * math.pi)], 900.0, 0.1)
    assert out["wheel.sinkage"].max() == pytest.approx(bound, abs=1e-9)
    unbounded = rover.run({"soil.cohesion": 20.0}, [Command(0.05, 0.0, 4 * math.pi)], 900.0, 0.1)
    assert unbounded["wheel.sinkage"].max() > 1.5 * bound


def test_motor_current_straight_and_turning_follows_the_wheel_forces(rover: FmuRunner) -> None:
    # I = sum (I0 + r |F_rim| / k_T). Straight on flat soil each rim pulls its compaction
    # resistance: 1.67 mA in all, near the paper's ~2 mA mean. A point turn shears the soil
    # sideways along the whole patch: 24 mA (docs/rover-model.md says where this departs from
    # the paper's Table 1).
    straight = rover.run({}, STRAIGHT, 60.0, 0.1)
    assert straight["wheel.current"][FIRST_PASS].sum() == pytest.approx(
        soil_model.straight_current(), rel=0.02)
    turn = rover.run({"controller.heading_feedback": 0.0}, [Command(0.05, 0.0, math.pi / 2)],
                     100.0, 0.1)
    assert turn["wheel.current"][400].sum() == pytest.approx(soil_model.point_turn_current(),
                                                             rel=0.02)


@pytest.mark.parametrize("cohesion", [50.0, 250.0, 700.0])
def test_turning_current_is_cohesion_dominated_lateral_shear_of_the_pressed_patch(
        rover: FmuRunner, cohesion: float) -> None:
    # In milli-g the cohesive strength of the pressed patch, b sqrt(2 r z) c, is several times
    # the wheel load (3.3x at 50 Pa, 9.8x at 250 Pa, 19x at 700 Pa), so scrubbing the patch
    # sideways in a turn costs current that grows with the cohesion (16.5, 24.4, 33.2 mA), not
    # with the load: Bekker's lateral strength A c + W tan(phi) of a sunken wheel. The
    # expectation is the yaw-moment balance of tests/fmu/soil_model.py at that cohesion.
    turn = rover.run({"controller.heading_feedback": 0.0, "soil.cohesion": cohesion},
                     [Command(0.05, 0.0, math.pi / 2)], 100.0, 0.1)
    eta = soil_model.point_turn_efficiency(cohesion)
    sinkage = soil_model.slip_sinkage(
        soil_model.static_sinkage(soil_model.WHEEL_LOAD, cohesion), 1 - eta)
    cohesive = soil_model.WIDTH * soil_model.patch_length(sinkage) * cohesion
    assert cohesive > 3 * soil_model.WHEEL_LOAD  # cohesion, not weight, holds the patch
    assert turn["wheel.current"][400].sum() == pytest.approx(
        soil_model.point_turn_current(cohesion), rel=0.03)
    # the patch is no larger than the one the wheel presses: the FMU's sinkage is the balance's
    assert turn["wheel.sinkage"][400] == pytest.approx(np.full(4, sinkage), rel=0.03)


def test_a_rut_is_as_wide_as_the_patch_that_pressed_it_whatever_the_grid(
        rover: FmuRunner, tmp_path: Path) -> None:
    # Grid convergence (docs/rover-model.md, "The rut grid's resolution"): each cell keeps the
    # mean depth over its area, the fraction the patch covered times the patch's sinkage, so a
    # rut is as wide as the patch whatever the cells' alignment, and a rear wheel that partly
    # overlaps it finds the same overlap whether it starts a fraction of a cell to either side.
    # The S-bend of the example's smooth detour on the example's terrain (3 mm rough, 2°, no
    # rock), started up to 5 mm apart: its worst wheel's slip angle (95th percentile) at the
    # default 1 cm cells (43.18-43.38°) spreads 0.2° and stays within 0.5° of a 2.5 mm grid's
    # (43.65-43.71°). Marking every cell a patch sample fell in made ruts up to a cell wider and
    # moved it 44.6-47.8°.
    terrain = write_terrain(tmp_path / "rough.terrain", synthetic_terrain(
        size=4.0, cell=0.02, slope=math.radians(2), roughness=0.003, seed=11))
    chain = [Command(0.05, 0.2618, math.radians(30)), Command(0.05, 0.5236, math.radians(-60)),
             Command(0.05, 0.2618, math.radians(30))]

    def slip_angle(cell: float, dx: float, dy: float) -> float:
        out = rover.run({"terrain.file": str(terrain), "soil.grid_cell": cell, "initial.x": dx,
                         "initial.y": dy}, chain, 600.0, 0.1)
        driving = out["command"] >= 0
        assert driving[0] and not driving[-1]  # the chain finished
        worst = np.abs(out["wheel.slip_angle"][driving]).max(axis=1)
        return math.degrees(float(np.percentile(worst, 95)))

    starts = [(0.0, 0.0), (0.0, 5e-4), (0.0, -5e-4), (1e-3, 0.0), (2e-3, 0.0), (5e-3, 0.0),
              (0.0, 3e-3)]
    coarse = [slip_angle(0.01, dx, dy) for dx, dy in starts]
    fine = [slip_angle(0.0025, dx, dy) for dx, dy in starts[:2]]
    assert max(coarse) - min(coarse) < 0.5
    assert max(abs(c - float(np.mean(fine))) for c in coarse) < 1.0


def test_the_rut_grid_measures_a_patch_and_a_rut_edge_as_brute_force_does(
        tmp_path: Path) -> None:
    # tests/fmu/rut_geometry_driver.c, compiled with soil.c: (1) the covered fraction of a cell
    # under a patch at any heading against 160,000 points of the cell (the points resolve
    # 1/400 of a cell's side), and the fractions of every cell the patch touches summing to its
    # area; (2) a pressed half-plane at any angle and offset stored as cells' fractions, and the
    # points of its middle cell put on the pressed side by the edge line reconstructed from the
    # neighbours (Youngs' normal, Scardovelli & Zaleski's line constant) as the half-plane puts
    # them: 0.3 % misplaced, near the line where the stencil's normal is slightly off (5.5 %
    # with the line constant taken as the fraction itself).
    compiler = shutil.which("cc") or shutil.which("gcc")
    if compiler is None:
        pytest.skip("no C compiler")
    binary = tmp_path / "rut_geometry"
    subprocess.run([compiler, "-std=c99", "-O2", f"-I{source_dir() / 'sources'}",
                    str(Path(__file__).with_name("rut_geometry_driver.c")), "-lm", "-o",
                    str(binary)], check=True)
    printed = subprocess.run([str(binary)], capture_output=True, text=True, check=True).stdout
    figures = dict(line.split() for line in printed.splitlines())
    assert float(figures["overlap"]) < 0.002
    assert float(figures["sum"]) < 1e-9
    assert float(figures["misclassified"]) < 0.01
