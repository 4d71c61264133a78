/* Quasi-static planar force balance of the body: damped Newton on forces x, y and the yaw
 * moment, and the inertia bound between balances. docs/rover-model.md, "Quasi-static motion". */
#include <math.h>
#include <string.h>

#include "idefix.h"

#define SPEED_LIMIT 1.0        /* m/s, bound of the balance search (quasi-static speeds: mm/s) */
#define BALANCE_TOLERANCE 1e-4 /* residual of a balance, as a fraction of the weight m g */
#define DYNAMIC_SUBSTEPS 8     /* implicit sub-steps of a step the balance search failed on */

void balance_residual(Instance *inst, const double q[3], double gx, double gy, double out[3])
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
    balance_residual(inst, zero, gx, gy, r);
    for (i = 0; i < N_WHEELS; i++) {
        const Wheel *w = &inst->wheels[i];
        double f = w->capacity * janosi_mobilisation(w->contact_length, w->shear_K);
        hold += f;
        hold_moment += f * sqrt(w->px * w->px + w->py * w->py);
    }
    return sqrt(r[0] * r[0] + r[1] * r[1]) <= hold && fabs(r[2]) <= hold_moment;
}

/* Can the wheels' full-skid strength hold the in-plane gravity at all? */
int balance_can_hold(const Instance *inst)
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
int balance_solve(Instance *inst, double gx, double gy, double q[3], int from_rest)
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
        balance_residual(inst, q, gx, gy, r);
        return 1;
    }
    /* warm start: the previous velocity (or rest), or the ideal one if that balances better */
    if (from_rest) q[0] = q[1] = q[2] = 0.0;
    balance_residual(inst, q, gx, gy, r);
    guess[0] = inst->ctrl.active >= 0 ? inst->ctrl.commanded_speed : 0.0;
    guess[1] = 0.0;
    guess[2] = inst->ctrl.active >= 0 ? inst->ctrl.commanded_yaw_rate : 0.0;
    balance_residual(inst, guess, gx, gy, rg);
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
            balance_residual(inst, qp, gx, gy, rp);
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
            balance_residual(inst, trial, gx, gy, rt);
            if (norm3(rt, arm) < rn) break;
        }
        if (k == 12) break;
        memcpy(q, trial, sizeof(trial));
        memcpy(r, rt, sizeof(rt));
        if (fabs(lambda * dq[0]) + fabs(lambda * dq[1]) + fabs(lambda * dq[2] * arm) < 1e-11) break;
    }
    for (i = 0; i < 3; i++)
        if (!isfinite(q[i])) q[i] = 0.0;
    balance_residual(inst, q, gx, gy, r);  /* leave the wheel forces of the solution in place */
    return norm3(r, arm) <= BALANCE_TOLERANCE * scale;
}

/* The rover's inertia between quasi-static states: its velocity moves towards the balance
 * velocity no faster than the largest net force allows, i.e. the full-skid strength of all
 * wheels plus in-plane gravity for the translation and their moment for the yaw rate. */
void balance_limit_acceleration(Instance *inst, const double previous[3], double q[3], double dt)
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

/* Where the search fails on a balance that exists (a stiff corner of the regularised laws, or a
 * balance on a kink of them), the rover moves as Newton's second law says with the model's own
 * forces: M dq/dt = R(q), M = diag(m, m, I_z), from the previous velocity over the step, in
 * linearly implicit Euler sub-steps ((M/h - dR/dq) dq = R(q); the wheel and rock laws are stiff,
 * relaxation times of milliseconds, so an explicit step would oscillate). Where a balance
 * attracts the velocity this moves towards it (the residual about halves per sub-step); where the
 * net force stays (a wheel pressed against a rock with another lifted) the velocity changes by
 * what that force gives, whatever path the failed search took. In the body frame, without the
 * transport terms m omega (v, -u), neglected as in the balance itself. */
void balance_integrate(Instance *inst, double gx, double gy, const double previous[3], double dt,
                       double q[3])
{
    const double mass = inst->r[VR_ROVER_MASS], inertia = inst->r[VR_ROVER_YAW_INERTIA];
    const double arm = inst->r[VR_ROVER_HALF_TRACK];
    const double eps = inst->r[VR_SOLVER_VELOCITY_EPSILON];
    const double step[3] = {1e-3 * eps, 1e-3 * eps, 1e-3 * eps / arm};
    const double h = dt / DYNAMIC_SUBSTEPS;
    double r[3], jac[3][3], dq[3];
    int n, i, k;
    memcpy(q, previous, 3 * sizeof(double));
    for (n = 0; n < DYNAMIC_SUBSTEPS; n++) {
        balance_residual(inst, q, gx, gy, r);
        for (k = 0; k < 3; k++) {
            double qp[3], rp[3];
            memcpy(qp, q, sizeof(qp));
            qp[k] += step[k];
            balance_residual(inst, qp, gx, gy, rp);
            for (i = 0; i < 3; i++) jac[i][k] = -(rp[i] - r[i]) / step[k];
        }
        jac[0][0] += mass / h;
        jac[1][1] += mass / h;
        jac[2][2] += inertia / h;
        {
            /* A damping law's implicit step is never larger, in the kinetic-energy norm, than
             * its explicit one; a larger one means the one-sided differences across a kink of
             * the laws made the linearisation push instead of damp: take the explicit step. */
            double explicit_step[3] = {r[0] / mass * h, r[1] / mass * h, r[2] / inertia * h};
            double implicit_energy, explicit_energy;
            if (solve3(jac, r, dq) != 0) memcpy(dq, explicit_step, sizeof(dq));
            implicit_energy = mass * (dq[0] * dq[0] + dq[1] * dq[1]) + inertia * dq[2] * dq[2];
            explicit_energy = mass * (explicit_step[0] * explicit_step[0] +
                                      explicit_step[1] * explicit_step[1]) +
                              inertia * explicit_step[2] * explicit_step[2];
            if (!(implicit_energy <= explicit_energy)) memcpy(dq, explicit_step, sizeof(dq));
        }
        for (i = 0; i < 3; i++) q[i] += isfinite(dq[i]) ? dq[i] : 0.0;
    }
}
