/* Locomotion controller: executes the command chain. Kinematics identical to
 * idefix_rules/commands.py::command_kinematics: each side's path is dp -/+ b*dpsi (left/right),
 * the fastest side turns at the max wheel rate. Two modes (controller.heading_feedback):
 * 1 (default) closed-loop heading on the gyro's yaw measurement, as the flight software turns
 * telecommands into controlled trajectories; 0 open-loop on wheel odometry.
 * docs/rover-model.md, "Locomotion controller". */
#include <math.h>

#include "idefix.h"

static int command_is_empty(const Instance *inst, int k)
{
    double rate = inst->r[VR_CHAIN_MAX_WHEEL_RATE + k];
    double dp = inst->r[VR_CHAIN_DELTA_POSITION + k], dh = inst->r[VR_CHAIN_DELTA_HEADING + k];
    double b = inst->r[VR_ROVER_HALF_TRACK];
    /* any motion, however small, is a command (a subnormal turn too: arc_rates); without a
     * track a point turn moves no wheel */
    return rate == 0.0 || (dp == 0.0 && (dh == 0.0 || b == 0.0));
}

static int closed_loop(const Instance *inst)
{
    return inst->r[VR_CONTROLLER_HEADING_FEEDBACK] != 0.0;
}

/* Nominal wheel rates of an arc (dp, dh) with the fastest wheel at `rate`, and its duration.
 * Worked out, as command_kinematics does, on the arc scaled by a power of two (exact) that
 * brings its larger component to [0.5, 1): a turn by a subnormal angle keeps its rates (b * dh
 * would underflow to 0), and an arc of ordinary size gets the same values to the last bit. */
static void arc_rates(Instance *inst, double rate, double dp, double dh)
{
    Controller *c = &inst->ctrl;
    double radius = inst->r[VR_ROVER_WHEEL_RADIUS], b = inst->r[VR_ROVER_HALF_TRACK];
    double left, right, fastest, duration;
    int exponent;
    (void)frexp(fabs(dp) > fabs(dh) ? fabs(dp) : fabs(dh), &exponent);
    dp = ldexp(dp, -exponent);
    dh = ldexp(dh, -exponent);
    left = dp - b * dh;
    right = dp + b * dh;
    fastest = fabs(left) > fabs(right) ? fabs(left) : fabs(right);
    duration = fastest / (rate * radius);  /* of the scaled arc */
    c->duration = ldexp(duration, exponent);
    c->target_angle = ldexp(fastest / radius, exponent);
    c->rates[0] = c->rates[2] = left / duration / radius;   /* FL, RL */
    c->rates[1] = c->rates[3] = right / duration / radius;  /* FR, RR */
    c->fastest = fabs(left) > fabs(right) ? 0 : 1;
    c->commanded_speed = dp / duration;
    c->commanded_yaw_rate = dh / duration;
    /* a trapezoidal profile takes rate/acceleration longer than the ideal duration */
    c->ramp_time = inst->r[VR_CONTROLLER_WHEEL_ACCELERATION] > 0.0 ?
                   rate / inst->r[VR_CONTROLLER_WHEEL_ACCELERATION] : 0.0;
}

static void begin_command(Instance *inst, int k)
{
    Controller *c = &inst->ctrl;
    int i;

    /* empty commands (zero rate or zero motion) take no time, as in command_kinematics */
    while (k < c->count && command_is_empty(inst, k)) k++;
    for (i = 0; i < N_WHEELS; i++) {
        c->rates[i] = 0.0;
        c->stalled[i] = 0;
    }
    c->elapsed = 0.0;
    c->angle = 0.0;
    c->travel = 0.0;
    c->heading = 0.0;
    c->trimming = 0;
    c->settling = 0;
    c->settle_sign = 1.0;
    c->profile = 0.0;
    c->ramp_time = 0.0;
    c->window_progress = 0.0;
    c->window_commanded = 0.0;
    c->stuck = 0;
    if (k >= c->count) {
        c->active = -1;
        c->duration = 0.0;
        c->target_angle = 0.0;
        c->commanded_speed = 0.0;
        c->commanded_yaw_rate = 0.0;
        c->max_rate = c->delta_position = c->delta_heading = 0.0;
        return;
    }
    c->active = k;
    c->max_rate = fabs(inst->r[VR_CHAIN_MAX_WHEEL_RATE + k]);
    c->delta_position = inst->r[VR_CHAIN_DELTA_POSITION + k];
    c->delta_heading = inst->r[VR_CHAIN_DELTA_HEADING + k];
    arc_rates(inst, c->max_rate, c->delta_position, c->delta_heading);
}

/* Closed loop, after the distance: turn on the spot by the heading error left (`trim`). */
static void begin_trim(Instance *inst, double error)
{
    Controller *c = &inst->ctrl;
    c->trimming = 1;
    c->settling = 0;
    c->settle_sign = 1.0;
    c->elapsed = 0.0;
    c->profile = 0.0;
    c->window_progress = 0.0;
    c->window_commanded = 0.0;
    arc_rates(inst, c->max_rate, 0.0, error);
}

void controller_start(Instance *inst)
{
    Controller *c = &inst->ctrl;
    c->count = inst->chain_count < 0 ? 0 :
               (inst->chain_count > MAX_COMMANDS ? MAX_COMMANDS : inst->chain_count);
    begin_command(inst, 0);
}

/* Heading still to turn, measured by the gyro since the command started, rad. */
static double heading_error(const Controller *c)
{
    return c->delta_heading - c->heading;
}

/* Closed loop: does the command turn on the spot (point turn or trim)? */
static int turning_on_the_spot(const Controller *c)
{
    return c->trimming || c->delta_position == 0.0;
}

/* Trapezoid factor for the fastest wheel with `remaining` rad of its rotation left. */
static double ramp(const Instance *inst, double fastest_rate, double remaining, double dt)
{
    const Controller *c = &inst->ctrl;
    double accel = inst->r[VR_CONTROLLER_WHEEL_ACCELERATION], scale = 1.0;
    if (accel > 0.0) {
        double up = c->profile + accel * dt / fastest_rate;
        double down = sqrt(2.0 * accel * remaining) / fastest_rate;  /* room left to stop */
        scale = up < down ? up : down;
        if (scale > 1.0) scale = 1.0;
    }
    return scale;
}

/* Closed loop: a wheel's corrected rate kept within [floor, 2 - floor] times its feed-forward
 * rate (same sign) and at most the command's rate. The gyro loop steers the arc it was given;
 * it never stops an inner wheel (which would pivot the rover about it and skid it) nor reverses
 * one, and what the band cannot correct during the arc the trim turns on the spot after it. */
static double corrected_rate(double forward, double wanted, double floor, double max_rate)
{
    double low = floor * forward, high = (2.0 - floor) * forward, rate = wanted;
    if (low > high) {
        double swap = low;
        low = high;
        high = swap;
    }
    if (rate < low) rate = low;
    if (rate > high) rate = high;
    if (rate > max_rate) rate = max_rate;
    if (rate < -max_rate) rate = -max_rate;
    return rate;
}

/* Sets every wheel's rate for the next step of length dt. Open loop: all rates share one profile
 * factor, so the arc keeps its shape; it ramps up and down at controller.wheel_acceleration (for
 * the fastest wheel) and the last step turns the wheels only as far as the odometry target.
 * Closed loop: the same profile on the distance left (mean odometry of both sides), plus a yaw
 * correction proportional to the gyro heading's lag behind the arc's heading at that distance;
 * on the spot, the profile runs on the gyro heading left. */
void controller_step(Instance *inst, double dt)
{
    Controller *c = &inst->ctrl;
    double radius = inst->r[VR_ROVER_WHEEL_RADIUS], b = inst->r[VR_ROVER_HALF_TRACK];
    double fastest_rate, remaining, scale, correction = 0.0, rates[N_WHEELS];
    int i;
    if (c->active < 0) {
        for (i = 0; i < N_WHEELS; i++) inst->wheels[i].rate = 0.0;
        return;
    }
    fastest_rate = fabs(c->rates[c->fastest]);
    if (!closed_loop(inst)) {
        remaining = c->target_angle - c->angle;
        if (remaining < 0.0) remaining = 0.0;
        scale = ramp(inst, fastest_rate, remaining, dt);
        if (fastest_rate * scale * dt > remaining) scale = remaining / (fastest_rate * dt);
    } else if (turning_on_the_spot(c) && c->settling) {
        /* within the tolerance: the wheels come to rest on the ramp, at the acceleration limit,
         * turning on the way they were (stopped in one step from the sqrt(2 a tol b / r) =
         * 0.016 rad/s the ramp below still has at the tolerance, the rates would step) */
        double accel = inst->r[VR_CONTROLLER_WHEEL_ACCELERATION];
        double left = fastest_rate > 0.0 && accel > 0.0 ? c->profile - accel * dt / fastest_rate
                                                         : 0.0;
        scale = c->settle_sign * (left > 0.0 ? left : 0.0);
    } else if (turning_on_the_spot(c)) {
        double error = heading_error(c);
        /* the gyro says which way is left to turn: an overshoot turns back */
        double sign = error * c->commanded_yaw_rate >= 0.0 ? 1.0 : -1.0;
        scale = sign * ramp(inst, fastest_rate, fabs(error) * b / radius, dt);
        c->settle_sign = sign;
    } else {
        double fraction = c->travel / c->delta_position, reference;
        double speed = fabs(c->commanded_speed);
        remaining = (1.0 - fraction) * fabs(c->delta_position);
        if (remaining < 0.0) remaining = 0.0;
        scale = ramp(inst, fastest_rate, remaining / fabs(c->delta_position) * c->target_angle,
                     dt);
        if (speed * scale * dt > remaining) scale = remaining / (speed * dt);
        reference = c->delta_heading * (fraction < 1.0 ? fraction : 1.0);
        correction = inst->r[VR_CONTROLLER_HEADING_GAIN] * (reference - c->heading);
    }
    c->profile = fabs(scale);
    for (i = 0; i < N_WHEELS; i++) {
        /* feed-forward: the command's kinematic rates; the heading correction, a yaw rate,
         * slows one side and speeds up the other (left wheels FL, RL slower for a left turn) */
        double side = (i == 0 || i == 2) ? -1.0 : 1.0;
        double forward = c->rates[i] * scale;
        rates[i] = forward + side * correction * b / radius;
        if (correction != 0.0)
            rates[i] = corrected_rate(forward, rates[i], inst->r[VR_CONTROLLER_RATE_FLOOR],
                                      c->max_rate);
    }
    for (i = 0; i < N_WHEELS; i++)
        inst->wheels[i].rate = c->stalled[i] ? 0.0 : rates[i];
}

/* Odometry, gyro, timeout, stall and the stuck observer, after the rover moved by `progress`
 * metres (signed along the commanded direction, plus the turned angle times half track) and
 * turned at `yaw_rate` (the body's, which the gyro measures with its bias and scale error). */
void controller_after_step(Instance *inst, double dt, double progress, double yaw_rate)
{
    Controller *c = &inst->ctrl;
    double max_torque = inst->r[VR_MOTOR_MAX_TORQUE], radius = inst->r[VR_ROVER_WHEEL_RADIUS];
    double window = inst->r[VR_CONTROLLER_STUCK_TIME];
    double tolerance = inst->r[VR_CONTROLLER_HEADING_TOLERANCE];
    double commanded;
    int i, done;
    if (c->active < 0) {
        c->stuck = 0;
        return;
    }
    c->elapsed += dt;
    c->angle += fabs(inst->wheels[c->fastest].rate) * dt;
    /* distance along the arc by odometry: mean of the left and right wheels (front pair) */
    c->travel += 0.5 * radius * (inst->wheels[0].rate + inst->wheels[1].rate) * dt;
    c->heading += ((1.0 + inst->r[VR_GYRO_SCALE_ERROR]) * yaw_rate + inst->r[VR_GYRO_BIAS]) * dt;
    /* a motor whose torque demand exceeds its limit stalls for the rest of the command */
    for (i = 0; i < N_WHEELS; i++)
        if (fabs(inst->wheels[i].thrust * radius) > max_torque) c->stalled[i] = 1;

    /* stuck observer: progress over an exponentially weighted window of length `window` */
    commanded = (fabs(c->commanded_speed) + fabs(c->commanded_yaw_rate) *
                 inst->r[VR_ROVER_HALF_TRACK]) * c->profile * dt;
    if (window > 0.0) {
        double decay = exp(-dt / window);
        c->window_progress = c->window_progress * decay + progress;
        c->window_commanded = c->window_commanded * decay + commanded;
        c->stuck = c->elapsed >= window &&
                   c->window_progress < inst->r[VR_CONTROLLER_STUCK_PROGRESS] * c->window_commanded;
    }
    if (c->elapsed >= inst->r[VR_CONTROLLER_TIMEOUT_FACTOR] * (c->duration + c->ramp_time)) {
        begin_command(inst, c->active + 1);
        return;
    }
    if (!closed_loop(inst)) {
        done = c->angle >= c->target_angle * (1.0 - 1e-12);
    } else if (turning_on_the_spot(c)) {
        /* within the tolerance the wheels ramp to rest (controller_step); done once they are */
        if (fabs(heading_error(c)) <= tolerance) c->settling = 1;
        done = c->settling && c->profile <= 0.0;
    } else if (c->travel / c->delta_position >= 1.0 - 1e-12) {
        /* the distance is covered: turn on the spot by what the heading still lacks */
        done = fabs(heading_error(c)) <= tolerance;
        if (!done) {
            begin_trim(inst, heading_error(c));
            return;
        }
    } else {
        done = 0;
    }
    if (done) begin_command(inst, c->active + 1);
}
