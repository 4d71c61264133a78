"""The documented soil and wheel equations (docs/rover-model.md, "Soil"), written again in
Python, independently of the C model, for the analytic expectations of the FMU tests.

Defaults are the FMU's: a 25 kg rover at Phobos' gravity on the default regolith.
"""

from __future__ import annotations

import itertools
import math

RADIUS, WIDTH, MASS, GRAVITY = 0.1, 0.06, 25.0, 0.0057
HALF_WHEELBASE, HALF_TRACK, COG = 0.2, 0.26, 0.25
COHESION, FRICTION, SHEAR_K = 250.0, math.radians(35.0), 0.012
K_C, K_PHI, N = 1400.0, 820e3, 1.0
REFERENCE_COHESION, REFERENCE_GRAVITY = 170.0, 1.62
GROUSER_HEIGHT, MAX_SINKAGE = 0.001, 0.03
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


def _arc_wheel_force(rim: float, px: float, py: float, u: float, omega: float
                     ) -> tuple[float, float]:
    """Force on the body of a wheel at (px, py) on flat fresh soil, rim speed `rim`, body
    moving at u with yaw rate omega: isotropic shear along the sliding direction with the
    shear displacement L |v_s| / max(|r w|, |v|), compaction against the rolling, bulldozing
    (at most the load) against the sideways motion, mobilised by the sideways displacement
    L |v_y| / max(|r w|, |v|); slip sinkage of the driving slip."""
    vx, vy = u - omega * py, omega * px
    sx, sy = rim - vx, -vy
    sliding = math.hypot(sx, sy)
    slip = 1 - vx / rim if abs(rim) >= abs(vx) else rim / vx - 1
    z = slip_sinkage(static_sinkage(WHEEL_LOAD), slip)
    shear = strength(WHEEL_LOAD, z) * janosi(
        shear_length(z) * sliding / max(abs(rim), math.hypot(vx, vy)))
    fx = shear * sx / sliding - compaction(z) * math.copysign(1.0, vx)
    sideways = janosi(shear_length(z) * abs(vy) / max(abs(rim), math.hypot(vx, vy)))
    fy = shear * sy / sliding - min(bulldozing(z), WHEEL_LOAD) * sideways * math.copysign(1.0, vy)
    return fx, fy


def arc_balance(rate_left: float, rate_right: float) -> tuple[float, float]:
    """Body speed and yaw rate (u, omega) of the rover on flat fresh soil with its left and
    right wheels at the given rates (rad/s): the forward force and the yaw moment of the four
    wheels at (+-a, +-b) balance (the lateral forces cancel by symmetry)."""
    from scipy.optimize import fsolve

    a, b = HALF_WHEELBASE, HALF_TRACK
    wheels = ((rate_left, a, b), (rate_right, a, -b), (rate_left, -a, b), (rate_right, -a, -b))

    def residual(q: list[float]) -> list[float]:
        forward = moment = 0.0
        for rate, px, py in wheels:
            fx, fy = _arc_wheel_force(RADIUS * rate, px, py, q[0], q[1])
            forward += fx
            moment += px * fy - py * fx
        return [forward / 0.01, moment / 0.01]

    mean = RADIUS * (rate_left + rate_right) / 2
    start = [0.9 * mean, 0.5 * RADIUS * (rate_right - rate_left) / (2 * b)]
    u, omega = fsolve(residual, start, xtol=1e-12)
    return float(u), float(omega)


def side_slope_crab(slope: float) -> float:
    """Downhill drift per metre (tan of the crab angle) driving straight across a side slope
    on fresh soil with the heading held: the four wheels' lateral shear and bulldozing, both
    mobilised by the sideways sliding v_y, carry m g sin(slope) (equal loads W cos(slope)/4,
    the load transfer to the downhill wheels left out)."""
    from scipy.optimize import brentq

    load = WHEEL_LOAD * math.cos(slope)
    rim = RADIUS * 0.05
    slip = driving_slip(load=load)
    z = slip_sinkage(static_sinkage(load), slip)
    u = rim * (1 - slip)

    def excess(v: float) -> float:
        sliding = math.hypot(rim - u, v)
        reference = max(rim, math.hypot(u, v))
        shear = strength(load, z) * janosi(shear_length(z) * sliding / reference) * v / sliding
        wedge = min(bulldozing(z), load) * janosi(shear_length(z) * v / reference)
        return 4 * (shear + wedge) - MASS * GRAVITY * math.sin(slope)

    return float(brentq(excess, 1e-12, rim)) / u
