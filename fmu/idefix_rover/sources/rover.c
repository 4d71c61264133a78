/* Rover: pose from the wheel contacts, quasi-static planar force balance, integration.
 * Equations and assumptions: docs/rover-model.md. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "idefix.h"

#define GRADE_PROBE 0.005      /* m, half distance of the grade finite difference */
#define BLOCK_PROBE 0.002      /* m, look-ahead for a rock face above the axle */
#define MAX_SOIL_GRADE 1.3     /* rad, largest grade of the DEM under a wheel (not on rocks) */
#define NO_ROCK_LIMIT (-1e299)
#define SPEED_LIMIT 1.0        /* m/s, bound of the balance search (quasi-static speeds: mm/s) */
#define BALANCE_TOLERANCE 1e-4 /* residual of a balance, as a fraction of the weight m g */

static const double SIDE_X[N_WHEELS] = {1.0, 1.0, -1.0, -1.0};  /* FL FR RL RR: front +1 */
static const double SIDE_Y[N_WHEELS] = {1.0, -1.0, 1.0, -1.0};  /* left +1 */

typedef struct {
    double x, y, yaw;
} Pose;

/* Wheel-centre height at (x, y) with heading (hx, hy): soil surface minus sinkage, or the
 * rock envelope where that is higher. */
static double centre_height(const Instance *inst, const Wheel *w, double x, double y, double hx,
                            double hy, int *on_rock, double *contact_d, double *contact_z)
{
    double radius = inst->r[VR_ROVER_WHEEL_RADIUS], width = inst->r[VR_ROVER_WHEEL_WIDTH];
    double soil = terrain_height(&inst->terrain, x, y) - w->sinkage + radius;
    double rock = rock_wheel_centre(&inst->terrain, x, y, hx, hy, radius, width, contact_d,
                                    contact_z);
    /* a rock point above the axle is a face the wheel runs into, not a support */
    *on_rock = rock > soil && *contact_z <= soil;
    return *on_rock ? rock : soil;
}

static void wheel_position(const Instance *inst, const Pose *p, const Wheel *w, double *wx,
                           double *wy)
{
    double c = cos(p->yaw), s = sin(p->yaw);
    (void)inst;
    *wx = p->x + c * w->px - s * w->py;
    *wy = p->y + s * w->px + c * w->py;
}

/* Odometer of the wheel's contact over ground, and the extent of its patch (plus one rut-grid
 * cell, the resolution of the marks) across its direction of motion without the patch length:
 * the contact length is added by the caller. */
static void update_travel(Wheel *w, double hx, double hy, double width, double cell)
{
    double dx = w->wx - w->last_wx, dy = w->wy - w->last_wy, step = sqrt(dx * dx + dy * dy);
    if (w->travel_started) {
        w->travel += step;
        if (step > 1e-9) {
            double across = fabs(-dx * hy + dy * hx) / step;  /* |sin| of motion to heading */
            w->own_span = width * across + cell;
        }
    } else {
        w->own_span = cell;
        w->travel_started = 1;
    }
    w->last_wx = w->wx;
    w->last_wy = w->wy;
}

/* Heights, body plane (z, roll, pitch), loads and per-wheel soil state at the current pose. */
static void update_geometry(Instance *inst)
{
    const double radius = inst->r[VR_ROVER_WHEEL_RADIUS], width = inst->r[VR_ROVER_WHEEL_WIDTH];
    const double hw = inst->r[VR_ROVER_HALF_WHEELBASE], ht = inst->r[VR_ROVER_HALF_TRACK];
    const double mass = inst->r[VR_ROVER_MASS], g = inst->r[VR_ROVER_GRAVITY];
    const double cog = inst->r[VR_ROVER_COG_HEIGHT];
    const double mu = inst->r[VR_ROCK_FRICTION_COEFFICIENT];
    const SoilParameters *soil = &inst->soil;
    Pose pose = {inst->x, inst->y, inst->yaw};
    double hx = cos(inst->yaw), hy = sin(inst->yaw);
    double slope[N_WHEELS], contact_angle[N_WHEELS], mean = 0.0, sx = 0.0, sy = 0.0, sxx = 0.0, syy = 0.0;
    double plane_x, plane_y, gx, gy, gz;
    int i;

    for (i = 0; i < N_WHEELS; i++) {
        Wheel *w = &inst->wheels[i];
        double d, cz, ahead, behind;
        wheel_position(inst, &pose, w, &w->wx, &w->wy);
        update_travel(w, hx, hy, width, inst->grid.cell);
        w->centre_z = centre_height(inst, w, w->wx, w->wy, hx, hy, &w->on_rock, &d, &cz);
        /* on a rock: the contact normal's angle from the vertical in the wheel plane, exact
         * from the contact position (d ahead of the axle: climbing forward) */
        contact_angle[i] = asin(d / radius > 1.0 ? 1.0 : (d / radius < -1.0 ? -1.0 : d / radius));
        /* on soil: the grade of the soil under the wheel (a rock the wheel does not touch is
         * no part of its path's grade) */
        ahead = terrain_height(&inst->terrain, w->wx + GRADE_PROBE * hx, w->wy + GRADE_PROBE * hy);
        behind = terrain_height(&inst->terrain, w->wx - GRADE_PROBE * hx, w->wy - GRADE_PROBE * hy);
        slope[i] = (ahead - behind) / (2.0 * GRADE_PROBE);
        mean += 0.25 * (w->centre_z - radius);
        sx += (w->centre_z - radius) * w->px;
        sy += (w->centre_z - radius) * w->py;
        sxx += w->px * w->px;
        syy += w->py * w->py;
    }
    /* least-squares plane through the four contacts (symmetric layout: decoupled slopes) */
    plane_x = sx / sxx;
    plane_y = sy / syy;
    inst->pitch = -atan(plane_x);
    inst->roll = atan(plane_y);
    inst->z = mean + inst->r[VR_ROVER_BODY_CENTRE_HEIGHT];

    /* gravity in the body frame, R = Rz(yaw) Ry(pitch) Rx(roll), z up */
    gx = g * sin(inst->pitch);
    gy = -g * sin(inst->roll) * cos(inst->pitch);
    gz = g * cos(inst->pitch) * cos(inst->roll);

    /* A wheel on the far side of a rock, on a face steeper than the friction cone of the
     * contact (atan mu) in its direction of travel, cannot rest on it: it slides off and drops
     * (slowly in milli-g), the chassis rocking onto the other wheels. Its static share of the
     * load goes to them instead of a face that could carry it only by pushing the rover on. */
    {
        double total = 0.0, kept = 0.0;
        for (i = 0; i < N_WHEELS; i++) {
            Wheel *w = &inst->wheels[i];
            double dir = w->rate > 0.0 ? 1.0 : (w->rate < 0.0 ? -1.0 : (inst->u >= 0.0 ? 1.0 : -1.0));
            double load = mass * gz / 4.0 + SIDE_X[i] * mass * gx * cog / (4.0 * hw) +
                          SIDE_Y[i] * mass * gy * cog / (4.0 * ht);
            w->load = load > 0.0 ? load : 0.0;
            w->dropping = w->on_rock && dir * (contact_angle[i] - atan(plane_x)) < -atan(mu);
            total += w->load;
            if (!w->dropping) kept += w->load;
        }
        for (i = 0; i < N_WHEELS; i++) {
            Wheel *w = &inst->wheels[i];
            if (kept <= 0.0) w->dropping = 0;
            else w->load = w->dropping ? 0.0 : w->load * total / kept;
        }
    }

    for (i = 0; i < N_WHEELS; i++) {
        Wheel *w = &inst->wheels[i];
        double path = w->on_rock ? contact_angle[i] :
                      fmax(-MAX_SOIL_GRADE, fmin(MAX_SOIL_GRADE, atan(slope[i])));
        double grade = path - atan(plane_x);
        /* loads: static sharing on four wheels with load transfer from the in-plane gravity,
         * set above */
        w->grade = grade;
        if (w->on_rock) {
            w->capacity = mu * w->load;
            w->contact_length = inst->r[VR_ROCK_CONTACT_LENGTH];
            w->shear_K = inst->r[VR_ROCK_SHEAR_K];
            w->resistance = 0.0;
            w->sinkage = 0.0;
            w->rut_depth = 0.0;
            w->disturbed = 0.0;
        } else {
            double z0 = bekker_static_sinkage(soil, w->load, radius, width);
            double zs = slip_sinkage(z0, w->slip);
            double patch = sqrt(2.0 * radius * zs);
            RutState rut = soil_query(&inst->grid, w->wx, w->wy, hx, hy, patch, width, i,
                                      w->travel, w->own_span + w->contact_length);
            double cohesion = soil->cohesion *
                              (1.0 - rut.disturbed * (1.0 - soil->rut_cohesion_factor));
            w->rut_depth = rut.rut_depth;
            w->disturbed = rut.disturbed;
            /* multi-pass: a wheel in a rut sinks on by a fraction of its first-pass sinkage */
            double rut_floor = rut.rut_depth + soil->multipass_factor * rut.disturbed * zs;
            w->sinkage = zs > rut_floor ? zs : rut_floor;
            w->contact_length = sqrt(2.0 * radius * w->sinkage);
            w->capacity = width * w->contact_length * cohesion + w->load * tan(soil->friction_angle);
            w->shear_K = soil->K;
            w->resistance = compaction_resistance(soil, w->sinkage, rut.rut_depth, width);
        }
    }
    inst->gx = gx;
    inst->gy = gy;
}

/* A rock face above the axle just ahead in the driving direction blocks the wheel. */
static void update_blocking(Instance *inst)
{
    const double radius = inst->r[VR_ROVER_WHEEL_RADIUS], width = inst->r[VR_ROVER_WHEEL_WIDTH];
    double hx = cos(inst->yaw), hy = sin(inst->yaw);
    int i;
    for (i = 0; i < N_WHEELS; i++) {
        Wheel *w = &inst->wheels[i];
        double dir = w->rate > 0.0 ? 1.0 : (w->rate < 0.0 ? -1.0 : (inst->u >= 0.0 ? 1.0 : -1.0));
        double d, cz;
        double probe_x = w->wx + dir * BLOCK_PROBE * hx, probe_y = w->wy + dir * BLOCK_PROBE * hy;
        double env = rock_wheel_centre(&inst->terrain, probe_x, probe_y, hx, hy, radius, width,
                                       &d, &cz);
        w->blocked = (env > NO_ROCK_LIMIT && cz > w->centre_z + 1e-6 && d * dir > 0.0) ?
                     (int)dir : 0;
    }
}

static void residual(Instance *inst, const double q[3], double gx, double gy, double out[3])
{
    const double radius = inst->r[VR_ROVER_WHEEL_RADIUS], mass = inst->r[VR_ROVER_MASS];
    const double mu = inst->r[VR_ROCK_FRICTION_COEFFICIENT];
    const double eps = inst->r[VR_SOLVER_VELOCITY_EPSILON];
    int i;
    out[0] = mass * gx;
    out[1] = mass * gy;
    out[2] = 0.0;
    for (i = 0; i < N_WHEELS; i++) {
        Wheel *w = &inst->wheels[i];
        double fx, fy, thrust;
        wheel_forces(w, radius, mu, q[0], q[1], q[2], eps, &fx, &fy, &thrust);
        w->fx = fx;
        w->fy = fy;
        w->thrust = thrust;
        out[0] += fx;
        out[1] += fy;
        out[2] += w->px * fy - w->py * fx;
    }
}

static double norm3(const double r[3], double arm)
{
    return sqrt(r[0] * r[0] + r[1] * r[1] + (r[2] / arm) * (r[2] / arm));
}

static int solve3(double a[3][3], const double b[3], double x[3])
{
    double det = a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1]) -
                 a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0]) +
                 a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0]);
    int k;
    if (!(fabs(det) > 1e-300) || !isfinite(det)) return -1;
    for (k = 0; k < 3; k++) {
        double m[3][3];
        memcpy(m, a, sizeof(m));
        m[0][k] = b[0];
        m[1][k] = b[1];
        m[2][k] = b[2];
        x[k] = (m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) -
                m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
                m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])) / det;
    }
    return 0;
}

/* The wheels alone, with motors holding, resist sliding as long as gravity and the contact
 * normals ask less than their full-skid shear strength: then the rover stands still. */
static int holds_still(Instance *inst, double gx, double gy)
{
    const double zero[3] = {0.0, 0.0, 0.0};
    double r[3], hold = 0.0, hold_moment = 0.0;
    int i;
    for (i = 0; i < N_WHEELS; i++)
        if (inst->wheels[i].rate != 0.0) return 0;
    residual(inst, zero, gx, gy, r);
    for (i = 0; i < N_WHEELS; i++) {
        const Wheel *w = &inst->wheels[i];
        double f = w->capacity * janosi_mobilisation(w->contact_length, w->shear_K);
        hold += f;
        hold_moment += f * sqrt(w->px * w->px + w->py * w->py);
    }
    return sqrt(r[0] * r[0] + r[1] * r[1]) <= hold && fabs(r[2]) <= hold_moment;
}

/* Can the wheels' full-skid strength hold the in-plane gravity at all? */
static int can_hold(const Instance *inst)
{
    double hold = 0.0;
    int i;
    for (i = 0; i < N_WHEELS; i++) {
        const Wheel *w = &inst->wheels[i];
        hold += w->capacity * janosi_mobilisation(w->contact_length, w->shear_K);
    }
    return inst->r[VR_ROVER_MASS] * sqrt(inst->gx * inst->gx + inst->gy * inst->gy) <= hold;
}

/* Damped Newton on the three equilibrium equations (forces x, y and yaw moment). Returns 1 when
 * a balance was found (residual below BALANCE_TOLERANCE of the forces at play), 0 when none
 * exists within SPEED_LIMIT: gravity then exceeds what the wheels can hold at any sliding
 * speed, e.g. downhill on a slope steeper than the soil carries. */
static int solve_balance(Instance *inst, double gx, double gy, double q[3], int from_rest)
{
    const double arm = inst->r[VR_ROVER_HALF_TRACK];
    const double eps = inst->r[VR_SOLVER_VELOCITY_EPSILON];
    const double step[3] = {1e-3 * eps, 1e-3 * eps, 1e-3 * eps / arm};
    double r[3], guess[3], rg[3], trust, fastest_rim = 0.0, scale;
    int iteration, i, k;

    /* Newton steps are bounded by a trust region of the order of the rim speeds (half of twice
     * the fastest rim speed, at least 1 cm/s: the far field, where every shear law saturates and
     * the residual is flat, is reached only in steps); 60 iterations reach 30 times that. The
     * velocity itself is bounded only by SPEED_LIMIT, far above any quasi-static balance. */
    for (i = 0; i < N_WHEELS; i++)
        if (fabs(inst->wheels[i].rate) > fastest_rim) fastest_rim = fabs(inst->wheels[i].rate);
    fastest_rim *= inst->r[VR_ROVER_WHEEL_RADIUS];
    trust = 2.0 * fastest_rim > 0.01 ? 2.0 * fastest_rim : 0.01;
    scale = inst->r[VR_ROVER_MASS] * inst->r[VR_ROVER_GRAVITY];

    if (holds_still(inst, gx, gy)) {
        q[0] = q[1] = q[2] = 0.0;
        residual(inst, q, gx, gy, r);
        return 1;
    }
    /* warm start: the previous velocity (or rest), or the ideal one if that balances better */
    if (from_rest) q[0] = q[1] = q[2] = 0.0;
    residual(inst, q, gx, gy, r);
    guess[0] = inst->ctrl.active >= 0 ? inst->ctrl.commanded_speed : 0.0;
    guess[1] = 0.0;
    guess[2] = inst->ctrl.active >= 0 ? inst->ctrl.commanded_yaw_rate : 0.0;
    residual(inst, guess, gx, gy, rg);
    if (norm3(rg, arm) < norm3(r, arm)) {
        memcpy(q, guess, sizeof(guess));
        memcpy(r, rg, sizeof(rg));
    }
    for (iteration = 0; iteration < 60; iteration++) {
        double jac[3][3], dq[3], rn = norm3(r, arm), trial[3], rt[3], lambda = 1.0;
        if (rn < 1e-10) break;  /* N: forces are of order 0.01-0.1 N */
        for (k = 0; k < 3; k++) {
            double qp[3], rp[3];
            memcpy(qp, q, sizeof(qp));
            qp[k] += step[k];
            residual(inst, qp, gx, gy, rp);
            for (i = 0; i < 3; i++) jac[i][k] = (rp[i] - r[i]) / step[k];
        }
        if (solve3(jac, r, dq) != 0) break;
        {
            double size = fabs(dq[0]) + fabs(dq[1]) + fabs(dq[2] * arm);
            if (size > 0.5 * trust)
                for (i = 0; i < 3; i++) dq[i] *= 0.5 * trust / size;
        }
        for (k = 0; k < 12; k++, lambda *= 0.5) {
            for (i = 0; i < 3; i++) trial[i] = q[i] - lambda * dq[i];
            for (i = 0; i < 3; i++) {
                double limit = i == 2 ? SPEED_LIMIT / arm : SPEED_LIMIT;
                trial[i] = trial[i] > limit ? limit : (trial[i] < -limit ? -limit : trial[i]);
            }
            residual(inst, trial, gx, gy, rt);
            if (norm3(rt, arm) < rn) break;
        }
        if (k == 12) break;
        memcpy(q, trial, sizeof(trial));
        memcpy(r, rt, sizeof(rt));
        if (fabs(lambda * dq[0]) + fabs(lambda * dq[1]) + fabs(lambda * dq[2] * arm) < 1e-11) break;
    }
    for (i = 0; i < 3; i++)
        if (!isfinite(q[i])) q[i] = 0.0;
    residual(inst, q, gx, gy, r);  /* leave the wheel forces of the solution in place */
    return norm3(r, arm) <= BALANCE_TOLERANCE * scale;
}

/* The rover's inertia between quasi-static states: its velocity moves towards the balance
 * velocity no faster than the largest net force allows, i.e. the full-skid strength of all
 * wheels plus in-plane gravity for the translation and their moment for the yaw rate. */
static void limit_acceleration(Instance *inst, const double previous[3], double q[3], double dt)
{
    const double mass = inst->r[VR_ROVER_MASS], inertia = inst->r[VR_ROVER_YAW_INERTIA];
    double force = mass * sqrt(inst->gx * inst->gx + inst->gy * inst->gy), moment = 0.0;
    double du = q[0] - previous[0], dv = q[1] - previous[1], dw = q[2] - previous[2];
    double step, largest;
    int i;
    for (i = 0; i < N_WHEELS; i++) {
        const Wheel *w = &inst->wheels[i];
        double hold = w->capacity * janosi_mobilisation(w->contact_length, w->shear_K);
        force += hold;
        moment += hold * sqrt(w->px * w->px + w->py * w->py);
    }
    step = sqrt(du * du + dv * dv);
    largest = force / mass * dt;
    if (step > largest) {
        q[0] = previous[0] + du * largest / step;
        q[1] = previous[1] + dv * largest / step;
    }
    largest = inertia > 0.0 ? moment / inertia * dt : fabs(dw);
    if (fabs(dw) > largest) q[2] = previous[2] + (dw > 0.0 ? largest : -largest);
}

static void move(Instance *inst, const double q[3], double dt, double fraction)
{
    double c_pitch = cos(inst->pitch), c_roll = cos(inst->roll);
    double dyaw = q[2] * dt * fraction, mid = inst->yaw + 0.5 * dyaw;
    double fx = q[0] * dt * fraction * c_pitch, fy = q[1] * dt * fraction * c_roll;
    inst->x += fx * cos(mid) - fy * sin(mid);
    inst->y += fx * sin(mid) + fy * cos(mid);
    inst->yaw += dyaw;
}

/* After a move, would any wheel have to touch a rock above where its axle was? */
static int penetrates(const Instance *inst, const double prev_centre[N_WHEELS])
{
    const double radius = inst->r[VR_ROVER_WHEEL_RADIUS], width = inst->r[VR_ROVER_WHEEL_WIDTH];
    Pose pose = {inst->x, inst->y, inst->yaw};
    double hx = cos(inst->yaw), hy = sin(inst->yaw);
    int i;
    for (i = 0; i < N_WHEELS; i++) {
        double wx, wy, d, cz, env;
        wheel_position(inst, &pose, &inst->wheels[i], &wx, &wy);
        env = rock_wheel_centre(&inst->terrain, wx, wy, hx, hy, radius, width, &d, &cz);
        if (env > NO_ROCK_LIMIT && cz > prev_centre[i] + 1e-6) return 1;
    }
    return 0;
}

static double wheel_slip(double rim, double vx, double eps)
{
    double s;
    if (fabs(rim) < 1e-12 && fabs(vx) < eps) return 0.0;
    if (fabs(rim) >= fabs(vx)) s = 1.0 - vx / rim;
    else s = rim / vx - 1.0;
    return s > 1.0 ? 1.0 : (s < -1.0 ? -1.0 : s);
}

void rover_step(Instance *inst, double dt)
{
    const double radius = inst->r[VR_ROVER_WHEEL_RADIUS], width = inst->r[VR_ROVER_WHEEL_WIDTH];
    const double eps = inst->r[VR_SOLVER_VELOCITY_EPSILON];
    const double i0 = inst->r[VR_MOTOR_NO_LOAD_CURRENT], kt = inst->r[VR_MOTOR_TORQUE_CONSTANT];
    double q[3] = {inst->u, inst->v, inst->omega}, gx, gy, prev_centre[N_WHEELS];
    double x0 = inst->x, y0 = inst->y, yaw0 = inst->yaw, fraction = 1.0, progress, hx, hy;
    int i, k;

    controller_step(inst, dt);
    update_blocking(inst);
    gx = inst->gx;
    gy = inst->gy;
    {
        const double previous[3] = {inst->u, inst->v, inst->omega};
        double r[3];
        int found = solve_balance(inst, gx, gy, q, 0);
        if (!found) {
            memcpy(q, previous, sizeof(previous));
            found = solve_balance(inst, gx, gy, q, 1);
        }
        /* Without a balance the rover slides only where physics says none exists: the wheels'
         * full-skid strength cannot hold the in-plane gravity. Otherwise the search failed on a
         * balance that exists (a stiff corner of the regularised laws): the velocity stays
         * within the rim speeds as in the search and follows it as far as inertia allows. */
        inst->sliding = !found && !can_hold(inst);
        if (!found && !inst->sliding) {
            double bound = 0.0;
            for (i = 0; i < N_WHEELS; i++)
                if (fabs(inst->wheels[i].rate) * radius > bound) bound = fabs(inst->wheels[i].rate) * radius;
            bound = 2.0 * bound > 0.01 ? 2.0 * bound : 0.01;
            for (i = 0; i < 3; i++) {
                double limit = i == 2 ? bound / inst->r[VR_ROVER_HALF_TRACK] : bound;
                if (!isfinite(q[i])) q[i] = 0.0;
                q[i] = q[i] > limit ? limit : (q[i] < -limit ? -limit : q[i]);
            }
        }
        if (inst->sliding) {
            /* No quasi-static balance: the net force accelerates the rover (Newton's second
             * law with the wheel forces at the present velocity), an uncontrolled slide. */
            const double mass = inst->r[VR_ROVER_MASS], inertia = inst->r[VR_ROVER_YAW_INERTIA];
            memcpy(q, previous, sizeof(previous));
            residual(inst, previous, gx, gy, r);
            q[0] += r[0] / mass * dt;
            q[1] += r[1] / mass * dt;
            q[2] += r[2] / inertia * dt;
        } else {
            limit_acceleration(inst, previous, q, dt);
        }
        residual(inst, q, gx, gy, r);  /* wheel forces at the velocity actually reached */
    }

    for (i = 0; i < N_WHEELS; i++) prev_centre[i] = inst->wheels[i].centre_z;
    move(inst, q, dt, 1.0);
    /* never step into a rock face: bisect the step back to a contact below the axles */
    for (k = 0; k < 8 && penetrates(inst, prev_centre); k++) {
        fraction *= 0.5;
        inst->x = x0;
        inst->y = y0;
        inst->yaw = yaw0;
        move(inst, q, dt, fraction);
    }
    if (k == 8 && penetrates(inst, prev_centre)) {
        inst->x = x0;
        inst->y = y0;
        inst->yaw = yaw0;
        fraction = 0.0;
    }
    inst->u = q[0] * fraction;
    inst->v = q[1] * fraction;
    inst->omega = q[2] * fraction;
    inst->time += dt;

    for (i = 0; i < N_WHEELS; i++) {
        Wheel *w = &inst->wheels[i];
        double vx = inst->u - inst->omega * w->py, vy = inst->v + inst->omega * w->px;
        w->slip = wheel_slip(radius * w->rate, vx, eps);
        w->slip_angle = sqrt(vx * vx + vy * vy) > eps ? atan2(vy, fabs(vx)) : 0.0;
        w->current = (w->rate != 0.0 ? i0 : 0.0) + fabs(w->thrust * radius) / kt;
        inst->energy += w->current * dt;
    }
    /* net progress along the commanded motion (backward motion counts against it) */
    progress = (inst->ctrl.commanded_speed >= 0.0 ? inst->u : -inst->u) * dt +
               (inst->ctrl.commanded_yaw_rate >= 0.0 ? inst->omega : -inst->omega) *
               inst->r[VR_ROVER_HALF_TRACK] * dt;
    controller_after_step(inst, dt, progress);

    update_geometry(inst);
    hx = cos(inst->yaw);
    hy = sin(inst->yaw);
    for (i = 0; i < N_WHEELS; i++) {
        Wheel *w = &inst->wheels[i];
        if (!w->on_rock && w->load > 0.0)
            soil_mark(&inst->grid, w->wx, w->wy, hx, hy, w->contact_length, width, w->sinkage, i,
                      w->travel, w->own_span + w->contact_length);
    }
}

/* Allowed range of every Real parameter: [lo, hi], an open end where marked. Ranges keep the
 * equations defined (tan of the friction angle, Bekker exponent, positive step and masses) and
 * the assumptions of the model (fractions in [0, 1], milli-g quasi-statics). */
typedef struct {
    int vr;
    const char *name;
    double lo, hi;
    int lo_open, hi_open;
} Range;

static const Range RANGES[] = {
    {VR_ROVER_MASS, "rover.mass", 0.0, 1e4, 1, 0},
    {VR_ROVER_GRAVITY, "rover.gravity", 0.0, 30.0, 1, 0},
    {VR_ROVER_WHEEL_RADIUS, "rover.wheel_radius", 0.0, 2.0, 1, 0},
    {VR_ROVER_WHEEL_WIDTH, "rover.wheel_width", 0.0, 2.0, 1, 0},
    {VR_ROVER_HALF_TRACK, "rover.half_track", 0.0, 10.0, 1, 0},
    {VR_ROVER_HALF_WHEELBASE, "rover.half_wheelbase", 0.0, 10.0, 1, 0},
    {VR_ROVER_YAW_INERTIA, "rover.yaw_inertia", 0.0, 1e6, 1, 0},
    {VR_ROVER_COG_HEIGHT, "rover.cog_height", 0.0, 10.0, 0, 0},
    {VR_ROVER_BODY_CENTRE_HEIGHT, "rover.body_centre_height", 0.0, 10.0, 0, 0},
    {VR_SOIL_K_C, "soil.k_c", 0.0, 1e9, 0, 0},
    {VR_SOIL_K_PHI, "soil.k_phi", 0.0, 1e12, 0, 0},
    {VR_SOIL_N, "soil.n", 0.0, 2.5, 0, 1},
    {VR_SOIL_COHESION, "soil.cohesion", 0.0, 1e6, 0, 0},
    {VR_SOIL_FRICTION_ANGLE, "soil.friction_angle", 0.0, 1.3962634015954636, 0, 0},  /* 80 deg */
    {VR_SOIL_SHEAR_MODULUS_K, "soil.shear_modulus_K", 0.0, 1.0, 1, 0},
    {VR_SOIL_RUT_COHESION_FACTOR, "soil.rut_cohesion_factor", 0.0, 1.0, 0, 0},
    {VR_SOIL_MULTIPASS_FACTOR, "soil.multipass_factor", 0.0, 2.0, 0, 0},
    {VR_SOIL_GRID_CELL, "soil.grid_cell", 0.0, 1.0, 1, 0},
    {VR_ROCK_FRICTION_COEFFICIENT, "rock.friction_coefficient", 0.0, 2.0, 0, 0},
    {VR_ROCK_SHEAR_K, "rock.shear_K", 0.0, 0.1, 1, 0},
    {VR_ROCK_CONTACT_LENGTH, "rock.contact_length", 0.0, 1.0, 1, 0},
    {VR_MOTOR_NO_LOAD_CURRENT, "motor.no_load_current", 0.0, 100.0, 0, 0},
    {VR_MOTOR_TORQUE_CONSTANT, "motor.torque_constant", 0.0, 1e4, 1, 0},
    {VR_MOTOR_MAX_TORQUE, "motor.max_torque", 0.0, 1e4, 1, 0},
    {VR_CONTROLLER_WHEEL_ACCELERATION, "controller.wheel_acceleration", 0.0, 100.0, 0, 0},
    {VR_CONTROLLER_TIMEOUT_FACTOR, "controller.timeout_factor", 1.0, 1000.0, 0, 0},
    {VR_CONTROLLER_STUCK_TIME, "controller.stuck_time", 0.0, 1e5, 1, 0},
    {VR_CONTROLLER_STUCK_PROGRESS, "controller.stuck_progress", 0.0, 1.0, 0, 0},
    {VR_INITIAL_X, "initial.x", -1e6, 1e6, 0, 0},
    {VR_INITIAL_Y, "initial.y", -1e6, 1e6, 0, 0},
    {VR_INITIAL_YAW, "initial.yaw", -1e6, 1e6, 0, 0},
    {VR_SOLVER_STEP, "solver.step", 0.0, 1.0, 1, 0},
    {VR_SOLVER_VELOCITY_EPSILON, "solver.velocity_epsilon", 0.0, 1e-3, 1, 0},
};

/* Every parameter in its range, else a message naming it, its value and the range. */
static int check_parameters(const Instance *inst, char *message, size_t message_size)
{
    size_t k;
    int i;
    for (k = 0; k < sizeof(RANGES) / sizeof(RANGES[0]); k++) {
        const Range *range = &RANGES[k];
        double value = inst->r[range->vr];
        int below = range->lo_open ? !(value > range->lo) : !(value >= range->lo);
        int above = range->hi_open ? !(value < range->hi) : !(value <= range->hi);
        if (below || above || !isfinite(value)) {
            snprintf(message, message_size, "parameter %s = %.17g out of range: allowed %c%g, %g%c",
                     range->name, value, range->lo_open ? '(' : '[', range->lo, range->hi,
                     range->hi_open ? ')' : ']');
            return -1;
        }
    }
    if (!(inst->r[VR_SOIL_K_C] > 0.0 || inst->r[VR_SOIL_K_PHI] > 0.0)) {
        snprintf(message, message_size, "parameter soil.k_phi = %.17g out of range: soil.k_c and "
                 "soil.k_phi must not both be 0", inst->r[VR_SOIL_K_PHI]);
        return -1;
    }
    for (i = 0; i < inst->chain_count; i++) {
        static const char *names[3] = {"chain.max_wheel_rate", "chain.delta_position",
                                       "chain.delta_heading"};
        const int base[3] = {VR_CHAIN_MAX_WHEEL_RATE, VR_CHAIN_DELTA_POSITION,
                             VR_CHAIN_DELTA_HEADING};
        int a;
        for (a = 0; a < 3; a++) {
            double value = inst->r[base[a] + i];
            if (!isfinite(value) || (a == 0 && value < 0.0)) {
                snprintf(message, message_size, "parameter %s[%d] = %.17g out of range: allowed "
                         "%s", names[a], i, value, a == 0 ? "[0, inf)" : "finite values");
                return -1;
            }
        }
    }
    return 0;
}

int rover_initialise(Instance *inst, char *message, size_t message_size)
{
    double x_min, y_min, x_max, y_max, cell = inst->r[VR_SOIL_GRID_CELL];
    int i;
    SoilParameters *s = &inst->soil;

    if (check_parameters(inst, message, message_size) != 0) return -1;
    s->k_c = inst->r[VR_SOIL_K_C];
    s->k_phi = inst->r[VR_SOIL_K_PHI];
    s->n = inst->r[VR_SOIL_N];
    s->cohesion = inst->r[VR_SOIL_COHESION];
    s->friction_angle = inst->r[VR_SOIL_FRICTION_ANGLE];
    s->K = inst->r[VR_SOIL_SHEAR_MODULUS_K];
    s->rut_cohesion_factor = inst->r[VR_SOIL_RUT_COHESION_FACTOR];
    s->multipass_factor = inst->r[VR_SOIL_MULTIPASS_FACTOR];

    if (terrain_load(&inst->terrain, inst->terrain_file, message, message_size) != 0) return -1;
    if (inst->terrain.loaded) {
        x_min = inst->terrain.x0 - 0.5;
        y_min = inst->terrain.y0 - 0.5;
        x_max = inst->terrain.x0 + (double)(inst->terrain.nx - 1) * inst->terrain.cell + 0.5;
        y_max = inst->terrain.y0 + (double)(inst->terrain.ny - 1) * inst->terrain.cell + 0.5;
    } else {
        x_min = inst->r[VR_INITIAL_X] - 5.0;
        y_min = inst->r[VR_INITIAL_Y] - 5.0;
        x_max = inst->r[VR_INITIAL_X] + 5.0;
        y_max = inst->r[VR_INITIAL_Y] + 5.0;
    }
    /* keep the grid allocation across resets when its extent is unchanged */
    if (inst->grid.sinkage && inst->grid.x0 == x_min && inst->grid.y0 == y_min &&
        inst->grid.nx == (long)ceil((x_max - x_min) / inst->grid.cell) + 1 &&
        inst->grid.ny == (long)ceil((y_max - y_min) / inst->grid.cell) + 1 &&
        (inst->grid.cell == cell || inst->grid.nx * inst->grid.ny > MAX_GRID_CELLS / 2)) {
        soil_grid_clear(&inst->grid);
    } else if (soil_grid_init(&inst->grid, x_min, y_min, x_max, y_max, cell) != 0) {
        snprintf(message, message_size, "out of memory for the soil grid");
        return -1;
    }

    for (i = 0; i < N_WHEELS; i++) {
        Wheel *w = &inst->wheels[i];
        memset(w, 0, sizeof(*w));
        w->px = SIDE_X[i] * inst->r[VR_ROVER_HALF_WHEELBASE];
        w->py = SIDE_Y[i] * inst->r[VR_ROVER_HALF_TRACK];
    }
    inst->x = inst->r[VR_INITIAL_X];
    inst->y = inst->r[VR_INITIAL_Y];
    inst->yaw = inst->r[VR_INITIAL_YAW];
    inst->u = inst->v = inst->omega = 0.0;
    inst->sliding = 0;
    inst->energy = 0.0;
    controller_start(inst);
    update_geometry(inst);
    rover_write_outputs(inst);
    return 0;
}

void rover_write_outputs(Instance *inst)
{
    int i;
    inst->r[VR_T] = inst->time;
    inst->r[VR_X] = inst->x;
    inst->r[VR_Y] = inst->y;
    inst->r[VR_Z] = inst->z;
    inst->r[VR_ROLL] = inst->roll;
    inst->r[VR_PITCH] = inst->pitch;
    inst->r[VR_YAW] = inst->yaw;
    for (i = 0; i < N_WHEELS; i++) {
        const Wheel *w = &inst->wheels[i];
        inst->r[VR_WHEEL_RATE + i] = w->rate;
        inst->r[VR_WHEEL_SLIP + i] = w->slip;
        inst->r[VR_WHEEL_SLIP_ANGLE + i] = w->slip_angle;
        inst->r[VR_WHEEL_SINKAGE + i] = w->sinkage;
        inst->r[VR_WHEEL_CURRENT + i] = w->current;
        inst->r[VR_WHEEL_LOAD + i] = w->load;
    }
    inst->r[VR_ENERGY] = inst->energy;
    inst->r[VR_COMMAND] = (double)inst->ctrl.active;
    /* stuck: no progress during a command, or an uncontrolled slide (no balance) at any time */
    inst->r[VR_STUCK] = (double)(inst->ctrl.stuck || inst->sliding);
}
