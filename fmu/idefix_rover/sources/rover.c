/* Rover: body plane and loads from the contacts, soil state of each wheel, one integration step,
 * initialisation and outputs. Contacts: contact.c, balance: balance.c, loads: loads.c.
 * Equations and assumptions: docs/rover-model.md. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "idefix.h"

#define MAX_SOIL_GRADE 1.3     /* rad, largest grade of the DEM under a wheel (not on rocks) */


/* Contacts, body plane (z, roll, pitch), loads and per-wheel ground state at the current pose. */
static void update_geometry(Instance *inst)
{
    const double radius = inst->r[VR_ROVER_WHEEL_RADIUS];
    double slope[N_WHEELS], contact_angle[N_WHEELS], mean = 0.0, sx = 0.0, sy = 0.0, sxx = 0.0, syy = 0.0;
    double plane_x, plane_y;
    int i;

    contact_update(inst, contact_angle, slope);
    for (i = 0; i < N_WHEELS; i++) {
        const Wheel *w = &inst->wheels[i];
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

    loads_update(inst, contact_angle);
    for (i = 0; i < N_WHEELS; i++) {
        Wheel *w = &inst->wheels[i];
        double path = w->on_rock ? contact_angle[i] :
                      fmax(-MAX_SOIL_GRADE, fmin(MAX_SOIL_GRADE, atan(slope[i])));
        w->grade = path - atan(plane_x);
        w->path_angle = path;
        w->pitch = inst->pitch;
        wheel_ground_state(inst, i);
    }
    {
        double strength = 0.0;
        for (i = 0; i < N_WHEELS; i++) strength += inst->wheels[i].capacity;
        for (i = 0; i < N_WHEELS; i++)
            inst->wheels[i].push_limit = strength - inst->wheels[i].capacity;
    }
}

static void move(Instance *inst, const double q[3], double dt)
{
    double c_pitch = cos(inst->pitch), c_roll = cos(inst->roll);
    double dyaw = q[2] * dt, mid = inst->yaw + 0.5 * dyaw;
    double fx = q[0] * dt * c_pitch, fy = q[1] * dt * c_roll;
    inst->x += fx * cos(mid) - fy * sin(mid);
    inst->y += fx * sin(mid) + fy * cos(mid);
    inst->yaw += dyaw;
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
    double x0 = inst->x, y0 = inst->y, yaw0 = inst->yaw, progress, hx, hy;
    int i, k;

    controller_step(inst, dt);
    contact_update_blocking(inst);
    gx = inst->gx;
    gy = inst->gy;
    {
        const double previous[3] = {inst->u, inst->v, inst->omega};
        double r[3];
        int found = balance_solve(inst, gx, gy, q, 0);
        if (!found) {
            memcpy(q, previous, sizeof(previous));
            found = balance_solve(inst, gx, gy, q, 1);
        }
        /* No balance found: the rover moves as Newton's second law gives with the forces at
         * play, integrated implicitly over the step from the previous velocity. It slides
         * (stuck) only where physics says no balance exists: the wheels' full-skid strength
         * cannot hold the in-plane gravity; otherwise the search failed on a stiff corner or a
         * kink of the regularised laws. */
        inst->sliding = !found && !balance_can_hold(inst);
        if (!found) {
            balance_integrate(inst, gx, gy, previous, dt, q);
        } else {
            balance_limit_acceleration(inst, previous, q, dt);
        }
        balance_residual(inst, q, gx, gy, r);  /* wheel forces at the velocity actually reached */
    }

    for (i = 0; i < N_WHEELS; i++) prev_centre[i] = inst->wheels[i].centre_z;
    move(inst, q, dt);
    /* Rock faces above the axle are one-sided constraints: a wheel that moved into one is pushed
     * out against it, the rest of the motion kept (a pivot). Only if no push frees it (a face
     * reached by the yaw alone) is the step's rotation, then all of it, undone. */
    for (k = 0; k < 2 * N_WHEELS; k++) {
        int wheel = contact_penetrating_wheel(inst, prev_centre);
        double reach = fabs(q[0]) * dt + inst->r[VR_ROVER_HALF_TRACK] * fabs(q[2]) * dt + 0.002;
        if (wheel < 0) break;
        if (contact_push_out(inst, wheel, prev_centre, reach)) continue;
        if (inst->yaw != yaw0) {
            double keep[3] = {q[0], q[1], 0.0};
            inst->x = x0;
            inst->y = y0;
            inst->yaw = yaw0;
            move(inst, keep, dt);
        } else {
            inst->x = x0;
            inst->y = y0;
            break;
        }
    }
    /* the velocity actually reached (slip, progress and the next warm start follow it) */
    {
        double dx = inst->x - x0, dy = inst->y - y0, mid = 0.5 * (inst->yaw + yaw0);
        inst->u = (dx * cos(mid) + dy * sin(mid)) / (dt * cos(inst->pitch));
        inst->v = (-dx * sin(mid) + dy * cos(mid)) / (dt * cos(inst->roll));
        inst->omega = (inst->yaw - yaw0) / dt;
    }
    inst->time += dt;

    for (i = 0; i < N_WHEELS; i++) {
        Wheel *w = &inst->wheels[i];
        double vx = inst->u - inst->omega * w->py, vy = inst->v + inst->omega * w->px;
        double along = wheel_path_speed(w, vx);
        w->slip = wheel_slip(radius * w->rate, along, eps);
        w->step_travel = fmax(fabs(radius * w->rate), sqrt(vx * vx + vy * vy)) * dt;
        /* a wheel turning against a face above its axle without getting on (under 5 % of its
         * rim speed) for controller.stuck_time truly cannot progress: `stuck`, the run goes on */
        if (w->blocked && w->rate != 0.0 && vx * w->blocked < 0.05 * fabs(radius * w->rate))
            w->blocked_time += dt;
        else
            w->blocked_time = 0.0;
        w->slip_angle = sqrt(along * along + vy * vy) > eps ? atan2(vy, fabs(along)) : 0.0;
        /* slip and slip angle are those of a contact: a wheel the step's loads left without
         * any (lifted, load 0) neither slips nor skids, whatever its rim and hub do, and its
         * rim digs nothing (docs/rover-model.md, "Outputs") */
        if (w->load <= 0.0) {
            w->slip = 0.0;
            w->slip_angle = 0.0;
        }
        w->current = (w->rate != 0.0 ? i0 : 0.0) + fabs(w->thrust * radius) / kt;
        inst->energy += w->current * dt;
    }
    /* net progress along the commanded motion (backward motion counts against it); each part
     * counts only if commanded: a straight drive pivoting about a held wheel progresses by its
     * forward distance, whichever way it yaws */
    progress = 0.0;
    if (inst->ctrl.commanded_speed != 0.0)
        progress += (inst->ctrl.commanded_speed > 0.0 ? inst->u : -inst->u) * dt;
    if (inst->ctrl.commanded_yaw_rate != 0.0)
        progress += (inst->ctrl.commanded_yaw_rate > 0.0 ? inst->omega : -inst->omega) *
                    inst->r[VR_ROVER_HALF_TRACK] * dt;
    controller_after_step(inst, dt, progress, inst->omega);

    update_geometry(inst);
    hx = cos(inst->yaw);
    hy = sin(inst->yaw);
    for (i = 0; i < N_WHEELS; i++) {
        Wheel *w = &inst->wheels[i];
        w->marked = !w->on_rock && w->load > 0.0;
        if (w->marked) {
            w->mark_span = w->own_span + w->patch_length;
            soil_mark(&inst->grid, w->wx, w->wy, hx, hy, w->patch_length, width, w->sinkage, i,
                      w->travel, w->mark_span);
        }
    }
}

int rover_initialise(Instance *inst, char *message, size_t message_size)
{
    double x_min, y_min, x_max, y_max, cell = inst->r[VR_SOIL_GRID_CELL];
    int i, status;
    SoilParameters *s = &inst->soil;

    if (parameters_check(inst, message, message_size) != 0) return -1;
    s->k_c = inst->r[VR_SOIL_K_C];
    s->k_phi = inst->r[VR_SOIL_K_PHI];
    s->n = inst->r[VR_SOIL_N];
    s->cohesion = inst->r[VR_SOIL_COHESION];
    s->friction_angle = inst->r[VR_SOIL_FRICTION_ANGLE];
    s->K = inst->r[VR_SOIL_SHEAR_MODULUS_K];
    s->rut_cohesion_factor = inst->r[VR_SOIL_RUT_COHESION_FACTOR];
    s->multipass_factor = inst->r[VR_SOIL_MULTIPASS_FACTOR];
    s->gravity = inst->r[VR_ROVER_GRAVITY];
    s->reference_gravity = inst->r[VR_SOIL_REFERENCE_GRAVITY];
    s->reference_cohesion = inst->r[VR_SOIL_REFERENCE_COHESION];
    s->max_sinkage = inst->r[VR_SOIL_MAX_SINKAGE];

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
        (double)inst->grid.nx == ceil((x_max - x_min) / inst->grid.cell) + 1.0 &&
        (double)inst->grid.ny == ceil((y_max - y_min) / inst->grid.cell) + 1.0 &&
        (inst->grid.cell == cell || inst->grid.nx * inst->grid.ny > MAX_GRID_CELLS / 2)) {
        soil_grid_clear(&inst->grid);
    } else if ((status = soil_grid_init(&inst->grid, x_min, y_min, x_max, y_max, cell)) != 0) {
        snprintf(message, message_size, status == -2 ? "terrain too large for the soil grid "
                 "(its extent is beyond a double)" : "out of memory for the soil grid");
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
    int i, wheel_stuck = 0;
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
    /* stuck: no progress during a command, a wheel that cannot get past a rock face, or an
     * uncontrolled slide (no balance) at any time */
    for (i = 0; i < N_WHEELS; i++)
        if (inst->wheels[i].blocked_time >= inst->r[VR_CONTROLLER_STUCK_TIME]) wheel_stuck = 1;
    inst->r[VR_STUCK] = (double)(inst->ctrl.stuck || inst->sliding || wheel_stuck);
}
