"""The documented soil and wheel equations (docs/rover-model.md, "Soil"), written again in
Python, independently of the C model, for the analytic expectations of the FMU tests.

Defaults are the FMU's: a 25 kg rover at Phobos' gravity on the default regolith.
"""

from __future__ import annotations

import itertools
import math

import numpy as np

RADIUS, WIDTH, MASS, GRAVITY = 0.1, 0.06, 25.0, 0.0057
HALF_WHEELBASE, HALF_TRACK, COG = 0.2, 0.26, 0.25
COHESION, FRICTION, SHEAR_K = 250.0, math.radians(35.0), 0.012
K_C, K_PHI, N = 1400.0, 820e3, 1.0
REFERENCE_COHESION, REFERENCE_GRAVITY = 170.0, 1.62
GROUSER_HEIGHT, MAX_SINKAGE = 0.001, 0.03
RUT_COHESION_FACTOR, MULTIPASS_FACTOR = 0.5, 0.3
WHEEL_LOAD = MASS * GRAVITY / 4


def modulus(cohesion: float = COHESION, k_phi: float = K_PHI) -> float:
    """Reece's form in Bekker's moduli: (c/c_ref) k_c / b + (g/g_ref) k_phi (n = 1)."""
    return K_C * cohesion / REFERENCE_COHESION / WIDTH + k_phi * GRAVITY / REFERENCE_GRAVITY


def static_sinkage(load: float, cohesion: float = COHESION, k_phi: float = K_PHI) -> float:
    """Rigid wheel on p = k z (n = 1): z = (3 W / (2 b k sqrt(2 r)))^(2/3), bounded."""
    k = modulus(cohesion, k_phi)
    z = (3 * load / ((3 - N) * WIDTH * k * math.sqrt(2 * RADIUS))) ** (2 / (2 * N + 1))
    return min(z, MAX_SINKAGE)


def slip_sinkage(static: float, slip: float) -> float:
    """Lyasko: z0 (1 + s) / (1 - s/2), s clipped to [0, 0.95]."""
    s = min(max(slip, 0.0), 0.95)
    return min(static * (1 + s) / (1 - s / 2), MAX_SINKAGE)


def patch_length(sinkage: float) -> float:
    """Geometric patch length sqrt(2 r z)."""
    return math.sqrt(2 * RADIUS * sinkage)


def shear_length(sinkage: float) -> float:
    """Length the shear displacement builds over: the patch, at least the grousers'
    sqrt(2 r h_g)."""
    return max(patch_length(sinkage), math.sqrt(2 * RADIUS * GROUSER_HEIGHT))


def strength(load: float, sinkage: float, cohesion: float = COHESION) -> float:
    """Mohr-Coulomb strength of the pressed patch: b sqrt(2 r z) c + W tan(phi)."""
    return WIDTH * patch_length(sinkage) * cohesion + load * math.tan(FRICTION)


def compaction(sinkage: float, cohesion: float = COHESION, k_phi: float = K_PHI) -> float:
    """Compaction resistance b k z^(n+1)/(n+1) on fresh soil."""
    return WIDTH * modulus(cohesion, k_phi) * sinkage ** (N + 1) / (N + 1)


def janosi(j: float, k: float = SHEAR_K) -> float:
    """Mean mobilised fraction over a patch sheared by j at its rear."""
    return 1 - k / j * (1 - math.exp(-j / k)) if j > 0 else 0.0


def driving_slip(cohesion: float = COHESION, k_phi: float = K_PHI,
                 load: float = WHEEL_LOAD) -> float:
    """Steady slip of a driven wheel on flat fresh soil: strength(z) f(L s) = compaction(z),
    z = the slip sinkage of the static one. On weak soil the slip sinkage gives a second,
    runaway balance at high slip; this is the first (driving) one."""
    from scipy.optimize import brentq

    z0 = static_sinkage(load, cohesion, k_phi)

    def excess(s: float) -> float:
        z = slip_sinkage(z0, s)
        return strength(load, z, cohesion) * janosi(shear_length(z) * s) - compaction(
            z, cohesion, k_phi)

    grid = [1e-7 + 0.005 * k for k in range(190)]
    low = next(a for a, b in itertools.pairwise(grid) if excess(a) < 0 <= excess(b))
    return float(brentq(excess, low, low + 0.005))


def rut_contact(load: float, slip: float, rut_depth: float) -> tuple[float, float, float, float]:
    """A wheel in a rut `rut_depth` deep, left by a wheel ahead: sinkage (from the original
    surface: its slip sinkage, at least the rut's floor plus the multi-pass fraction of it),
    strength, shear length and compaction resistance. The soil carries it only where the rim
    presses below the rut's floor (a soil point takes stress only where the wheel is below its
    deformed level: Project Chrono's SCM, `SCMDeformableTerrain`), so the strength acts on the
    arc below the floor, `b sqrt(2 r (z - d)) c_r + W tan(phi)`, with the remoulded cohesion
    c_r, and the compaction runs from the floor down: `b k (z^(n+1) - d^(n+1)) / (n+1)`."""
    zs = slip_sinkage(static_sinkage(load), slip)
    z = min(max(zs, rut_depth + MULTIPASS_FACTOR * zs), MAX_SINKAGE)
    pressed = math.sqrt(2 * RADIUS * max(z - rut_depth, 0.0))
    cohesion = COHESION * RUT_COHESION_FACTOR
    shear = max(pressed, math.sqrt(2 * RADIUS * GROUSER_HEIGHT))
    rolling = WIDTH * modulus() * (z ** (N + 1) - rut_depth ** (N + 1)) / (N + 1)
    return z, WIDTH * pressed * cohesion + load * math.tan(FRICTION), shear, rolling


def two_axle_slip(load: float = WHEEL_LOAD) -> float:
    """Steady slip of a straight drive on flat soil once the rear wheels run in the front
    wheels' ruts: all four rims turn at one rate and the body moves at one speed, so the four
    wheels share the slip s, and the fronts' net pull on fresh soil carries the rears' net
    drag in the ruts the fronts leave (their slip sinkage at s)."""
    from scipy.optimize import brentq

    def excess(s: float) -> float:
        z_front = slip_sinkage(static_sinkage(load), s)
        front = strength(load, z_front) * janosi(shear_length(z_front) * s) \
            - compaction(z_front)
        _, rear_strength, rear_shear, rear_rolling = rut_contact(load, s, z_front)
        return 2 * front + 2 * (rear_strength * janosi(rear_shear * s) - rear_rolling)

    return float(brentq(excess, 1e-7, 0.5))


def wheel_at_rest(load: float, cohesion: float = COHESION) -> tuple[float, float, float]:
    """Shear length, strength and compaction resistance of a wheel without slip sinkage."""
    z = static_sinkage(load, cohesion)
    return shear_length(z), strength(load, z, cohesion), compaction(z, cohesion)


def bulldozing(sinkage: float, cohesion: float = COHESION) -> float:
    """Lateral passive resistance beside a wheel: L z c K_c (Prandtl N_c), at most its load."""
    t = math.tan(FRICTION)
    n_q = math.exp(math.pi * t) * math.tan(math.pi / 4 + FRICTION / 2) ** 2
    n_c = (n_q - 1) / t
    k_c = (n_c - t) * math.cos(FRICTION) ** 2
    return patch_length(sinkage) * sinkage * cohesion * k_c


def _turning_wheel(eta: float, cohesion: float = COHESION) -> tuple[float, float, float, float]:
    """Sliding speed per unit commanded yaw rate, rim shear S, bulldozing and compaction of a
    point-turning wheel at efficiency eta; its rim slips by 1 - eta (Lyasko slip sinkage)."""
    a, b = HALF_WHEELBASE, HALF_TRACK
    z = slip_sinkage(static_sinkage(WHEEL_LOAD, cohesion), 1 - eta)
    sliding = math.hypot((1 - eta) * b, eta * a)
    reference = max(b, eta * math.hypot(a, b))
    shear = strength(WHEEL_LOAD, z, cohesion) * janosi(shear_length(z) * sliding / reference)
    # the passive wedge beside the wheel is mobilised by the patch's sideways displacement
    sideways = janosi(shear_length(z) * eta * a / reference)
    return (sliding, shear, min(bulldozing(z, cohesion), WHEEL_LOAD) * sideways,
            compaction(z, cohesion))


def point_turn_efficiency(cohesion: float = COHESION) -> float:
    """Body yaw rate over commanded yaw rate of a point turn on fresh soil: the yaw moment of
    the four wheels at (+-a, +-b) balances, each with isotropic shear S(j) along its sliding
    direction, the lateral bulldozing B against its sideways motion and the compaction
    resistance R_c against its rolling: S [(1-eta) b^2 - eta a^2] / |s| = a B + b R_c, with
    |s| = sqrt((1-eta)^2 b^2 + eta^2 a^2) per unit commanded yaw rate."""
    from scipy.optimize import brentq

    a, b = HALF_WHEELBASE, HALF_TRACK

    def moment(eta: float) -> float:
        sliding, shear, lateral, rolling = _turning_wheel(eta, cohesion)
        return shear * ((1 - eta) * b * b - eta * a * a) / sliding - a * lateral - b * rolling

    return float(brentq(moment, 1e-6, b * b / (a * a + b * b)))


NO_LOAD_CURRENT, TORQUE_CONSTANT = 0.0003, 2.0


def straight_current() -> float:
    """Total motor current driving straight on flat fresh soil: each wheel's thrust equals its
    compaction resistance, I = 4 (I0 + r R_c / k_T)."""
    z = slip_sinkage(static_sinkage(WHEEL_LOAD), driving_slip())
    return 4 * (NO_LOAD_CURRENT + RADIUS * compaction(z) / TORQUE_CONSTANT)


def point_turn_current(cohesion: float = COHESION) -> float:
    """Total motor current of a point turn on fresh soil at the balance of point_turn_efficiency:
    each wheel's shear along its rim, S (1 - eta) b / |s|, through the motor constant."""
    eta = point_turn_efficiency(cohesion)
    sliding, shear, _, _ = _turning_wheel(eta, cohesion)
    rim = shear * (1 - eta) * HALF_TRACK / sliding
    return 4 * (NO_LOAD_CURRENT + RADIUS * rim / TORQUE_CONSTANT)


def uphill_slip(slope: float, k_phi: float = K_PHI, cohesion: float = COHESION) -> float:
    """Steady slip driving straight up a uniform slope: the four wheels' net pull (strength
    f(L s) minus compaction, with slip sinkage and the loads shifted to the rear by the slope,
    W_i = m g (cos / 4 -+ sin h / (4 l))) carries m g sin(slope)."""
    from scipy.optimize import brentq

    normal, along = MASS * GRAVITY * math.cos(slope), MASS * GRAVITY * math.sin(slope)
    loads = [normal / 4 + side * along * COG / (4 * HALF_WHEELBASE) for side in (-1, -1, 1, 1)]

    def excess(s: float) -> float:
        pull = 0.0
        for load in loads:
            z = slip_sinkage(static_sinkage(load, cohesion, k_phi), s)
            pull += strength(load, z, cohesion) * janosi(shear_length(z) * s) - compaction(
                z, cohesion, k_phi)
        return pull - along

    return float(brentq(excess, 1e-7, 0.9))


def _arc_wheel_force(rim: float, px: float, py: float, u: float, v: float, omega: float,
                     rut_depth: float | None = None) -> tuple[float, float]:
    """Force on the body of a wheel at (px, py) on flat soil, rim speed `rim`, body moving at
    (u, v) with yaw rate omega: isotropic shear along the sliding direction with the shear
    displacement L |v_s| / max(|r w|, |v|), compaction against the rolling, bulldozing (at most
    the load) against the sideways motion, mobilised by the sideways displacement
    L |v_y| / max(|r w|, |v|); slip sinkage of the driving slip. On fresh soil, or with
    `rut_depth` in the rut a wheel ahead left (rut_contact)."""
    vx, vy = u - omega * py, v + omega * px
    sx, sy = rim - vx, -vy
    sliding = math.hypot(sx, sy)
    slip = 1 - vx / rim if abs(rim) >= abs(vx) else rim / vx - 1
    if rut_depth is None:
        z = slip_sinkage(static_sinkage(WHEEL_LOAD), slip)
        held, length, rolling, cohesion = strength(WHEEL_LOAD, z), shear_length(z), \
            compaction(z), COHESION
    else:
        z, held, length, rolling = rut_contact(WHEEL_LOAD, slip, rut_depth)
        cohesion = COHESION * RUT_COHESION_FACTOR
    reference = max(abs(rim), math.hypot(vx, vy))
    shear = held * janosi(length * sliding / reference)
    fx = shear * sx / sliding - rolling * math.copysign(1.0, vx)
    sideways = janosi(length * abs(vy) / reference)
    wedge = min(bulldozing(z, cohesion), WHEEL_LOAD) * sideways
    fy = shear * sy / sliding - wedge * math.copysign(1.0, vy)
    return fx, fy


def arc_balance(rate_left: float, rate_right: float,
                ruts: tuple[bool, bool] = (False, False)) -> tuple[float, float]:
    """(u, omega) of arc_velocity."""
    u, _, omega = arc_velocity(rate_left, rate_right, ruts)
    return u, omega


def arc_velocity(rate_left: float, rate_right: float,
                 ruts: tuple[bool, bool] = (False, False)) -> tuple[float, float, float]:
    """Body velocity (u, v, omega) of the rover on flat soil with its left and right
    wheels at the given rates (rad/s): the forward and lateral forces and the yaw moment of
    the four wheels at (+-a, +-b) balance. `ruts` (left, right): that side's rear wheel runs
    in the rut of the front wheel ahead of it (as deep as that wheel's slip sinkage; see
    rut_separation for when it does); otherwise every wheel is on fresh soil and v = 0 by
    symmetry. A rear wheel in a rut holds less than the front one, so the body side-slips."""
    from scipy.optimize import fsolve

    a, b = HALF_WHEELBASE, HALF_TRACK
    any_rut = any(ruts)

    def residual(q: list[float]) -> list[float]:
        u, v, omega = q if any_rut else (q[0], 0.0, q[1])
        forward = lateral = moment = 0.0
        for rate, py, rut in ((rate_left, b, ruts[0]), (rate_right, -b, ruts[1])):
            rim = RADIUS * rate
            vx = u - omega * py
            slip = 1 - vx / rim if abs(rim) >= abs(vx) else rim / vx - 1
            depth = slip_sinkage(static_sinkage(WHEEL_LOAD), slip) if rut else None
            for px, wheel_rut in ((a, None), (-a, depth)):
                fx, fy = _arc_wheel_force(rim, px, py, u, v, omega, wheel_rut)
                forward += fx
                lateral += fy
                moment += px * fy - py * fx
        return [forward / 0.01, lateral / 0.01, moment / 0.01] if any_rut \
            else [forward / 0.01, moment / 0.01]

    mean = RADIUS * (rate_left + rate_right) / 2
    yaw = 0.5 * RADIUS * (rate_right - rate_left) / (2 * b)
    solution = fsolve(residual, [0.9 * mean, 0.0, yaw] if any_rut else [0.9 * mean, yaw],
                      xtol=1e-12)
    return float(solution[0]), float(solution[1]) if any_rut else 0.0, float(solution[-1])


def rut_separation(side_radius: float) -> float:
    """Heading an arc turns before a side's rear wheel reaches the rut of its front wheel:
    about a centre abeam the body's middle both run on one circle of radius
    sqrt(R_side^2 + a^2), the front one 2 atan(a / R_side) ahead (R_side = R -+ b, the side's
    distance from the centre); a point turn's wheels are 2 atan(a / b) or 2 atan(b / a) apart
    on their common circle."""
    return 2 * math.atan2(HALF_WHEELBASE, abs(side_radius))


def arc_rut_separations(rate_inner: float, rate_outer: float) -> tuple[float, float]:
    """rut_separation of an arc's inner and outer side, on the circle the body turns on over
    fresh soil at these wheel rates (radius u / omega of arc_balance, wider than the commanded
    one by the skid)."""
    u, omega = arc_balance(rate_inner, rate_outer)
    return rut_separation(u / omega - HALF_TRACK), rut_separation(u / omega + HALF_TRACK)


def open_loop_arc_efficiency(radius: float, turn: float) -> float:
    """Heading reached over heading commanded by an open-loop arc of `radius` turning `turn`
    left at kinematic rates: the body turns at the efficiency of the balance (omega over the
    kinematic yaw rate) of each phase, fresh soil until a side's rear wheel reaches its front
    wheel's rut (rut_separation, in the body's heading, on the circle the body turns on over
    fresh soil: radius u / omega, wider than the commanded one by the skid), then with that
    rut."""
    ratio = (radius - HALF_TRACK) / (radius + HALF_TRACK)
    kinematic = RADIUS * 0.05 * (1 - ratio) / (2 * HALF_TRACK)
    inner, outer = arc_rut_separations(0.05 * ratio, 0.05)
    heading = commanded = 0.0
    for end in [*sorted({inner, outer}), math.inf]:
        ruts = (heading >= inner - 1e-12, heading >= outer - 1e-12)
        efficiency = arc_balance(0.05 * ratio, 0.05, ruts)[1] / kinematic
        if commanded + (end - heading) / efficiency >= turn:
            return (heading + (turn - commanded) * efficiency) / turn
        commanded += (end - heading) / efficiency
        heading = end
    raise AssertionError("unreachable")


def side_slope_crab(slope: float, ruts: bool = False) -> float:
    """Downhill drift per metre (tan of the crab angle) driving straight across a side slope
    with the heading held: the four wheels' lateral shear and bulldozing, both mobilised by
    the sideways sliding v_y, carry m g sin(slope) (equal loads W cos(slope)/4, the load
    transfer to the downhill wheels left out). On fresh soil, or with `ruts` the rear wheels
    in the ruts of the front ones (rut_contact: strength below the rut's floor, the remoulded
    cohesion in the wedge) and the four sharing the two-axle slip."""
    from scipy.optimize import brentq

    load = WHEEL_LOAD * math.cos(slope)
    rim = RADIUS * 0.05
    slip = driving_slip(load=load) if not ruts else two_axle_slip(load)
    z = slip_sinkage(static_sinkage(load), slip)
    u = rim * (1 - slip)
    wheels = [(strength(load, z), shear_length(z), min(bulldozing(z), load))] * 2
    if ruts:
        rear_z, held, length, _ = rut_contact(load, slip, z)
        wedge = min(bulldozing(rear_z, COHESION * RUT_COHESION_FACTOR), load)
        wheels += [(held, length, wedge)] * 2
    else:
        wheels *= 2

    def excess(v: float) -> float:
        sliding = math.hypot(rim - u, v)
        reference = max(rim, math.hypot(u, v))
        total = 0.0
        for held, length, wedge in wheels:
            total += held * janosi(length * sliding / reference) * v / sliding
            total += wedge * janosi(length * v / reference)
        return total - MASS * GRAVITY * math.sin(slope)

    return float(brentq(excess, 1e-12, rim)) / u


def balance_path(rates: np.ndarray, yaw: np.ndarray, command: np.ndarray, turns: list[float],
                 interval: float, every: int = 5) -> tuple[float, float]:
    """End position of a chain of arcs (heading changes `turns`, rad, one per command) from
    the wheel rates and headings a run sampled every `interval` s (`command`: its command
    index per sample): at every `every`-th sample of a command, the body velocity (u, v) of
    arc_velocity at the sample's left and right rates, turned to the sample's heading, with
    each side's rear wheel in its front wheel's rut once the command has turned by the
    rut_separation of the circle its body turns on over fresh soil (u / omega at the
    command's steady rates, the middle half of its samples)."""
    x = y = 0.0
    for k, turn in enumerate(turns):
        during = np.flatnonzero(command == k)
        steady = rates[during[len(during) // 4: 3 * len(during) // 4], :2].mean(axis=0)
        left_turn = turn > 0
        inner_rate, outer_rate = (steady[0], steady[1]) if left_turn else (steady[1], steady[0])
        inner, outer = arc_rut_separations(float(inner_rate), float(outer_rate))
        for j in during[::every]:
            left, right = float(rates[j, 0]), float(rates[j, 1])
            if left * right <= 0.0:  # the ramps' first instant and the trims on the spot
                continue
            turned = abs(yaw[j] - yaw[during[0]])
            ruts = (turned > inner, turned > outer)
            along, side, _ = arc_velocity(left, right, ruts if left_turn else ruts[::-1])
            x += (along * math.cos(yaw[j]) - side * math.sin(yaw[j])) * interval * every
            y += (along * math.sin(yaw[j]) + side * math.cos(yaw[j])) * interval * every
    return x, y
