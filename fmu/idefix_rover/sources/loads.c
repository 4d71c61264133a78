/* Wheel loads: static sharing on four wheels with the load transfer of the in-plane gravity,
 * and wheels sliding off a rock face. docs/rover-model.md, "Loads". */
#include <math.h>

#include "idefix.h"

const double SIDE_X[N_WHEELS] = {1.0, 1.0, -1.0, -1.0};  /* FL FR RL RR: front +1 */
const double SIDE_Y[N_WHEELS] = {1.0, -1.0, 1.0, -1.0};  /* left +1 */

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
    inst->gx = gx;
    inst->gy = gy;
}
