/* Wheel loads: static sharing on four wheels with the load transfer of the in-plane gravity,
 * and wheels sliding off a rock face. docs/rover-model.md, "Loads". */
#include <math.h>

#include "idefix.h"

const double SIDE_X[N_WHEELS] = {1.0, 1.0, -1.0, -1.0};  /* FL FR RL RR: front +1 */
const double SIDE_Y[N_WHEELS] = {1.0, -1.0, 1.0, -1.0};  /* left +1 */

/* Uneven ground under a rigid chassis: the four support heights h_i (soil surface, or the rock
 * contact) need not lie in a plane. Their twist w = sum s_i h_i / 4 (s_i = +1 for FL and RR,
 * -1 for FR and RL; zero for any plane) is taken up by the compliance of the supports, and the
 * only self-equilibrated load pattern on a rectangle is s_i T: the wheels of one diagonal gain
 * T, the others lose it. Compatibility, sum s_i (s_i T c_i) = 4 w, gives T = 4 w / sum c_i, with
 * c_i = c_leg + z_i / ((n + 1/2) W_i): the leg's compliance (rover.leg_compliance) in series
 * with that of a Bekker wheel (W grows as z^(n+1/2)), which is 0 on a rock. T is bounded where a wheel unloads: the chassis then rests on three wheels, the
 * diagonal pair carrying what the lifted wheel gave up. */
static void twist_loads(Instance *inst)
{
    const double radius = inst->r[VR_ROVER_WHEEL_RADIUS], width = inst->r[VR_ROVER_WHEEL_WIDTH];
    double twist = 0.0, compliance = 0.0, gain = 1e300, loss = 1e300, transfer;
    int i;
    for (i = 0; i < N_WHEELS; i++) {
        const Wheel *w = &inst->wheels[i];
        double sign = SIDE_X[i] * SIDE_Y[i];
        double support = w->centre_z - radius + (w->on_rock ? 0.0 : w->sinkage);
        twist += 0.25 * sign * support;
        compliance += inst->r[VR_ROVER_LEG_COMPLIANCE];
        if (!w->on_rock && w->load > 0.0)
            compliance += bekker_static_sinkage(&inst->soil, w->load, radius, width) /
                          ((inst->soil.n + 0.5) * w->load);
        /* largest transfer each way before a wheel of the losing diagonal lifts off */
        if (sign > 0.0 && w->load < loss) loss = w->load;
        if (sign < 0.0 && w->load < gain) gain = w->load;
    }
    transfer = compliance > 0.0 ? 4.0 * twist / compliance : (twist > 0.0 ? 1e300 : -1e300);
    if (twist == 0.0) transfer = 0.0;
    transfer = transfer > gain ? gain : (transfer < -loss ? -loss : transfer);
    for (i = 0; i < N_WHEELS; i++) {
        Wheel *w = &inst->wheels[i];
        double load = w->load + SIDE_X[i] * SIDE_Y[i] * transfer;
        w->load = load > 0.0 ? load : 0.0;
    }
}

/* Sets inst->gx, gy (in-plane gravity) and every wheel's load and `dropping` flag from the body
 * plane (inst->roll, pitch) and the contact angles on rocks. */
void loads_update(Instance *inst, const double contact_angle[N_WHEELS])
{
    const double hw = inst->r[VR_ROVER_HALF_WHEELBASE], ht = inst->r[VR_ROVER_HALF_TRACK];
    const double mass = inst->r[VR_ROVER_MASS], g = inst->r[VR_ROVER_GRAVITY];
    const double cog = inst->r[VR_ROVER_COG_HEIGHT];
    const double mu = inst->r[VR_ROCK_FRICTION_COEFFICIENT];
    const double plane_x = -tan(inst->pitch);
    double gx, gy, gz, total = 0.0, kept = 0.0;
    int i;

    /* gravity in the body frame, R = Rz(yaw) Ry(pitch) Rx(roll), z up */
    gx = g * sin(inst->pitch);
    gy = -g * sin(inst->roll) * cos(inst->pitch);
    gz = g * cos(inst->pitch) * cos(inst->roll);

    /* A wheel on the far side of a rock, on a face steeper than the friction cone of the
     * contact (atan mu) in its direction of travel, cannot rest on it: it slides off and drops
     * (slowly in milli-g), the chassis rocking onto the other wheels. Its static share of the
     * load goes to them instead of a face that could carry it only by pushing the rover on. */
    for (i = 0; i < N_WHEELS; i++) {
        double load = mass * gz / 4.0 + SIDE_X[i] * mass * gx * cog / (4.0 * hw) +
                      SIDE_Y[i] * mass * gy * cog / (4.0 * ht);
        inst->wheels[i].load = load > 0.0 ? load : 0.0;
    }
    twist_loads(inst);
    for (i = 0; i < N_WHEELS; i++) {
        Wheel *w = &inst->wheels[i];
        double dir = w->rate > 0.0 ? 1.0 : (w->rate < 0.0 ? -1.0 : (inst->u >= 0.0 ? 1.0 : -1.0));
        w->dropping = w->on_rock && dir * (contact_angle[i] - atan(plane_x)) < -atan(mu);
        total += w->load;
        if (!w->dropping) kept += w->load;
    }
    for (i = 0; i < N_WHEELS; i++) {
        Wheel *w = &inst->wheels[i];
        if (kept <= 0.0) w->dropping = 0;
        else w->load = w->dropping ? 0.0 : w->load * total / kept;
    }
    inst->gx = gx;
    inst->gy = gy;
}
