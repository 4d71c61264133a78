/* Contacts: where each wheel touches the terrain (soil or rock), its odometer over ground, the
 * grade under it, and the rock faces above the axle that block it. docs/rover-model.md, "Pose
 * from the wheel contacts" and "Rocks". */
#include <math.h>

#include "idefix.h"

#define GRADE_PROBE 0.005      /* m, half distance of the grade finite difference */
#define BLOCK_PROBE 0.002      /* m, look-ahead for a rock face above the axle */
#define FACE_TOLERANCE 1e-6    /* m, a rock point this far above the axle is a face */
#define PATH_TOLERANCE 1e-7    /* m, where along a move the wheel first touches a rock */
#define NO_ROCK_LIMIT (-1e299)

/* Is rock k a face the wheel runs into, rather than a support it rolls onto, as the wheel moves
 * from (x0, y0) to (x1, y1) (heading (hx, hy)) with its axle at height `axle`? A wheel rolling
 * onto a rock meets it with the contact below its axle, and the contact then moves up the rock
 * as the envelope lifts the wheel: continuously, so at the end of a step it may be above where
 * the axle was, never above where the axle is. A face taller than the axle instead enters the
 * footprint at the rim (or its side) with its top above the axle: the envelope jumps. So the
 * move is followed to its first touch of the rock (the envelope reaching the axle, by bisection
 * along the move) and the rock is a face if the contact there is above the axle. A wheel that
 * does not move (from = to) is judged at its place: a face if the contact is above its axle.
 * (d, z): the contact at (x1, y1), as rock_wheel_centre gives it; on return *d is the
 * contact's distance ahead of the axle at the first touch. */
static int rock_is_face(const Instance *inst, int k, double x0, double y0, double x1, double y1,
                        double hx, double hy, double axle, double *d, double z)
{
    const double radius = inst->r[VR_ROVER_WHEEL_RADIUS], width = inst->r[VR_ROVER_WHEEL_WIDTH];
    const Terrain *t = &inst->terrain;
    double lo = 0.0, hi = 1.0, length = hypot(x1 - x0, y1 - y0), d_hi = *d, z_hi = z, dk, zk;
    if (z <= axle + FACE_TOLERANCE) return 0;
    if (rock_wheel_centre(t, k, x0, y0, hx, hy, radius, width, &dk, &zk) >=
        axle - FACE_TOLERANCE) {
        *d = dk;  /* touching where it started */
        return zk > axle + FACE_TOLERANCE;
    }
    while ((hi - lo) * length > PATH_TOLERANCE) {
        double mid = 0.5 * (lo + hi);
        if (rock_wheel_centre(t, k, x0 + mid * (x1 - x0), y0 + mid * (y1 - y0), hx, hy, radius,
                              width, &dk, &zk) >= axle - FACE_TOLERANCE) {
            hi = mid;
            d_hi = dk;
            z_hi = zk;
        } else {
            lo = mid;
        }
    }
    *d = d_hi;
    return z_hi > axle + FACE_TOLERANCE;
}

/* Wheel-centre height at (x, y) with heading (hx, hy), reached from (x0, y0) with the axle at
 * `axle`: the soil surface minus sinkage, or the envelope of the rocks the wheel rolls onto
 * where that is higher (a rock met above the axle is a face, no support). */
static double centre_height(const Instance *inst, const Wheel *w, double x0, double y0,
                            double axle, double x, double y, double hx, double hy, int *on_rock,
                            double *contact_d)
{
    double radius = inst->r[VR_ROVER_WHEEL_RADIUS], width = inst->r[VR_ROVER_WHEEL_WIDTH];
    double soil = terrain_height(&inst->terrain, x, y) - w->support_sinkage + radius;
    double rock = NO_ROCK_LIMIT;
    int k;
    *contact_d = 0.0;
    for (k = 0; k < inst->terrain.n_rocks; k++) {
        double d, z, face_d;
        double env = rock_wheel_centre(&inst->terrain, k, x, y, hx, hy, radius, width, &d, &z);
        if (env <= rock || env <= soil) continue;
        face_d = d;
        if (rock_is_face(inst, k, x0, y0, x, y, hx, hy, axle, &face_d, z)) continue;
        rock = env;
        *contact_d = d;
    }
    *on_rock = rock > soil;
    return *on_rock ? rock : soil;
}

/* Would the wheel, moving from (x0, y0) to (x1, y1) with its axle at `axle`, run into a rock
 * face (in the direction `dir` along the heading only, when dir is not 0)? */
static int meets_face(const Instance *inst, double x0, double y0, double x1, double y1, double hx,
                      double hy, double axle, double dir)
{
    const double radius = inst->r[VR_ROVER_WHEEL_RADIUS], width = inst->r[VR_ROVER_WHEEL_WIDTH];
    int k;
    for (k = 0; k < inst->terrain.n_rocks; k++) {
        double d, z;
        if (rock_wheel_centre(&inst->terrain, k, x1, y1, hx, hy, radius, width, &d, &z) <=
            NO_ROCK_LIMIT)
            continue;
        if (rock_is_face(inst, k, x0, y0, x1, y1, hx, hy, axle, &d, z) &&
            (dir == 0.0 || d * dir > 0.0))
            return 1;
    }
    return 0;
}

void contact_wheel_position(const Instance *inst, double x, double y, double yaw, const Wheel *w,
                            double *wx, double *wy)
{
    double c = cos(yaw), s = sin(yaw);
    (void)inst;
    *wx = x + c * w->px - s * w->py;
    *wy = y + s * w->px + c * w->py;
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

/* Per wheel: world position, odometer, centre height (soil or rock envelope), and the angle of
 * its path: the contact angle on a rock, the soil grade along the heading otherwise. */
void contact_update(Instance *inst, double contact_angle[N_WHEELS], double soil_slope[N_WHEELS])
{
    const double radius = inst->r[VR_ROVER_WHEEL_RADIUS], width = inst->r[VR_ROVER_WHEEL_WIDTH];
    double hx = cos(inst->yaw), hy = sin(inst->yaw);
    int i;
    for (i = 0; i < N_WHEELS; i++) {
        Wheel *w = &inst->wheels[i];
        /* where the wheel was and its axle then (at the start: here, its axle on the soil) */
        int started = w->travel_started;
        double x0 = w->wx, y0 = w->wy, axle = w->centre_z, d, ahead, behind;
        contact_wheel_position(inst, inst->x, inst->y, inst->yaw, w, &w->wx, &w->wy);
        update_travel(w, hx, hy, width, inst->grid.cell);
        if (!started) {
            x0 = w->wx;
            y0 = w->wy;
            axle = terrain_height(&inst->terrain, w->wx, w->wy) - w->support_sinkage + radius;
        }
        w->centre_z = centre_height(inst, w, x0, y0, axle, w->wx, w->wy, hx, hy, &w->on_rock, &d);
        /* on a rock: the contact normal's angle from the vertical in the wheel plane, exact
         * from the contact position (d ahead of the axle: climbing forward) */
        contact_angle[i] = asin(d / radius > 1.0 ? 1.0 : (d / radius < -1.0 ? -1.0 : d / radius));
        /* on soil: the grade of the soil under the wheel (a rock the wheel does not touch is
         * no part of its path's grade) */
        ahead = terrain_height(&inst->terrain, w->wx + GRADE_PROBE * hx, w->wy + GRADE_PROBE * hy);
        behind = terrain_height(&inst->terrain, w->wx - GRADE_PROBE * hx, w->wy - GRADE_PROBE * hy);
        soil_slope[i] = (ahead - behind) / (2.0 * GRADE_PROBE);
    }
}

/* A rock face above the axle just ahead in the driving direction blocks the wheel. */
void contact_update_blocking(Instance *inst)
{
    double hx = cos(inst->yaw), hy = sin(inst->yaw);
    int i;
    for (i = 0; i < N_WHEELS; i++) {
        Wheel *w = &inst->wheels[i];
        double dir = w->rate > 0.0 ? 1.0 : (w->rate < 0.0 ? -1.0 : (inst->u >= 0.0 ? 1.0 : -1.0));
        double probe_x = w->wx + dir * BLOCK_PROBE * hx, probe_y = w->wy + dir * BLOCK_PROBE * hy;
        w->blocked = meets_face(inst, w->wx, w->wy, probe_x, probe_y, hx, hy, w->centre_z, dir) ?
                     (int)dir : 0;
    }
}

/* Would wheel i, moved from where it was at the start of the step to its place at the body
 * pose (x, y, yaw), have run into a rock face above where its axle was? */
static int wheel_penetrates(const Instance *inst, int i, double x, double y, double yaw,
                            const double prev_centre[N_WHEELS])
{
    const Wheel *w = &inst->wheels[i];
    double wx, wy;
    contact_wheel_position(inst, x, y, yaw, w, &wx, &wy);
    return meets_face(inst, w->wx, w->wy, wx, wy, cos(yaw), sin(yaw), prev_centre[i], 0.0);
}

/* After a move, the first wheel that would have to touch a rock above where its axle was, or -1. */
int contact_penetrating_wheel(const Instance *inst, const double prev_centre[N_WHEELS])
{
    int i;
    for (i = 0; i < N_WHEELS; i++)
        if (wheel_penetrates(inst, i, inst->x, inst->y, inst->yaw, prev_centre)) return i;
    return -1;
}

/* Least push (to 0.01 mm, at most `reach`) of the body along (ux, uy) that frees wheel i, or
 * -1 when none within reach does. */
static double least_push(const Instance *inst, int i, const double prev_centre[N_WHEELS],
                         double ux, double uy, double reach)
{
    double lo = 0.0, hi = reach;
    int k;
    if (wheel_penetrates(inst, i, inst->x + hi * ux, inst->y + hi * uy, inst->yaw, prev_centre))
        return -1.0;
    for (k = 0; k < 40 && hi - lo > 1e-8; k++) {
        double mid = 0.5 * (lo + hi);
        if (wheel_penetrates(inst, i, inst->x + mid * ux, inst->y + mid * uy, inst->yaw,
                             prev_centre))
            lo = mid;
        else
            hi = mid;
    }
    return hi;
}

/* One-sided rock contact: wheel i moved into a face above its axle. The body is pushed out by
 * the least distance that puts the wheel against the face instead of into it, back along the
 * heading (the way the wheel came), or across it, or both at 45° (whichever is least: the
 * face's normal is not known, these bracket it); the rest of the step (yaw, sliding along the
 * face) is kept, so a blocked wheel becomes a pivot. `reach` is the largest push tried.
 * Returns 0 when no push within reach frees the wheel. */
int contact_push_out(Instance *inst, int i, const double prev_centre[N_WHEELS], double reach)
{
    const Wheel *w = &inst->wheels[i];
    double dir = w->rate > 0.0 ? 1.0 : (w->rate < 0.0 ? -1.0 : (inst->u >= 0.0 ? 1.0 : -1.0));
    double hx = cos(inst->yaw), hy = sin(inst->yaw), best = -1.0, best_x = 0.0, best_y = 0.0;
    const double c45 = 0.7071067811865476;
    /* back along the heading, across it (left, right), and the two diagonals behind */
    double ux[5], uy[5];
    int k;
    ux[0] = -dir * hx;
    uy[0] = -dir * hy;
    ux[1] = -hy;
    uy[1] = hx;
    ux[2] = hy;
    uy[2] = -hx;
    ux[3] = c45 * (ux[0] + ux[1]);
    uy[3] = c45 * (uy[0] + uy[1]);
    ux[4] = c45 * (ux[0] + ux[2]);
    uy[4] = c45 * (uy[0] + uy[2]);
    for (k = 0; k < 5; k++) {
        double push = least_push(inst, i, prev_centre, ux[k], uy[k], reach);
        if (push >= 0.0 && (best < 0.0 || push < best)) {
            best = push;
            best_x = push * ux[k];
            best_y = push * uy[k];
        }
    }
    if (best < 0.0) return 0;
    inst->x += best_x;
    inst->y += best_y;
    return 1;
}
