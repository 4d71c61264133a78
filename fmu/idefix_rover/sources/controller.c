/* Locomotion controller: executes the command chain open-loop on wheel odometry.
 * Kinematics identical to idefix_rules/commands.py::command_kinematics: each side's path is
 * dp -/+ b*dpsi (left/right), the fastest side turns at the max wheel rate. */
#include <math.h>

#include "idefix.h"

static int command_is_empty(const Instance *inst, int k)
{
    double rate = inst->r[VR_CHAIN_MAX_WHEEL_RATE + k];
    double dp = inst->r[VR_CHAIN_DELTA_POSITION + k], dh = inst->r[VR_CHAIN_DELTA_HEADING + k];
    return rate == 0.0 || (dp == 0.0 && dh == 0.0);
}

static void begin_command(Instance *inst, int k)
{
    Controller *c = &inst->ctrl;
    double radius = inst->r[VR_ROVER_WHEEL_RADIUS], b = inst->r[VR_ROVER_HALF_TRACK];
    double rate, dp, dh, left, right, fastest;
    int i;

    /* empty commands (zero rate or zero motion) take no time, as in command_kinematics */
    while (k < c->count && command_is_empty(inst, k)) k++;
    for (i = 0; i < N_WHEELS; i++) {
        c->rates[i] = 0.0;
        c->stalled[i] = 0;
    }
    c->elapsed = 0.0;
    c->angle = 0.0;
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
        return;
    }
    rate = fabs(inst->r[VR_CHAIN_MAX_WHEEL_RATE + k]);
    dp = inst->r[VR_CHAIN_DELTA_POSITION + k];
    dh = inst->r[VR_CHAIN_DELTA_HEADING + k];
    left = dp - b * dh;
    right = dp + b * dh;
    fastest = fabs(left) > fabs(right) ? fabs(left) : fabs(right);
    c->active = k;
    c->duration = fastest / (rate * radius);
    c->target_angle = fastest / radius;
    c->rates[0] = c->rates[2] = left / c->duration / radius;   /* FL, RL */
    c->rates[1] = c->rates[3] = right / c->duration / radius;  /* FR, RR */
    c->fastest = fabs(left) > fabs(right) ? 0 : 1;
    c->commanded_speed = dp / c->duration;
    /* a trapezoidal profile takes rate/acceleration longer than the ideal duration */
    if (inst->r[VR_CONTROLLER_WHEEL_ACCELERATION] > 0.0)
        c->ramp_time = rate / inst->r[VR_CONTROLLER_WHEEL_ACCELERATION];
    c->commanded_yaw_rate = dh / c->duration;
}

void controller_start(Instance *inst)
{
    Controller *c = &inst->ctrl;
    c->count = inst->chain_count < 0 ? 0 :
               (inst->chain_count > MAX_COMMANDS ? MAX_COMMANDS : inst->chain_count);
    begin_command(inst, 0);
}

/* Sets every wheel's rate for the next step of length dt. All rates share one profile factor,
 * so the arc keeps its shape: it ramps up and down at controller.wheel_acceleration (for the
 * fastest wheel) and the last step turns the wheels only as far as the odometry target. */
void controller_step(Instance *inst, double dt)
{
    Controller *c = &inst->ctrl;
    double accel = inst->r[VR_CONTROLLER_WHEEL_ACCELERATION];
    double fastest_rate, remaining, scale = 1.0;
    int i;
    if (c->active < 0) {
        for (i = 0; i < N_WHEELS; i++) inst->wheels[i].rate = 0.0;
        return;
    }
    fastest_rate = fabs(c->rates[c->fastest]);
    remaining = c->target_angle - c->angle;
    if (remaining < 0.0) remaining = 0.0;
    if (accel > 0.0) {
        double up = c->profile + accel * dt / fastest_rate;
        double down = sqrt(2.0 * accel * remaining) / fastest_rate;  /* room left to stop */
        scale = up < down ? up : down;
        if (scale > 1.0) scale = 1.0;
    }
    if (fastest_rate * scale * dt > remaining) scale = remaining / (fastest_rate * dt);
    c->profile = scale;
    for (i = 0; i < N_WHEELS; i++)
        inst->wheels[i].rate = c->stalled[i] ? 0.0 : c->rates[i] * scale;
}

/* Odometry, timeout, stall and the stuck observer, after the rover moved by `progress` metres
 * (signed along the commanded direction, plus the turned angle times half track). */
void controller_after_step(Instance *inst, double dt, double progress)
{
    Controller *c = &inst->ctrl;
    double max_torque = inst->r[VR_MOTOR_MAX_TORQUE], radius = inst->r[VR_ROVER_WHEEL_RADIUS];
    double window = inst->r[VR_CONTROLLER_STUCK_TIME];
    double commanded;
    int i;
    if (c->active < 0) {
        c->stuck = 0;
        return;
    }
    c->elapsed += dt;
    c->angle += fabs(inst->wheels[c->fastest].rate) * dt;
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
    if (c->angle >= c->target_angle * (1.0 - 1e-12) ||
        c->elapsed >= inst->r[VR_CONTROLLER_TIMEOUT_FACTOR] * (c->duration + c->ramp_time))
        begin_command(inst, c->active + 1);
}
