/* Wheel loads: static sharing on four wheels with the load transfer of the in-plane gravity,
 * the support of a wheel on a rock at its contact point, and wheels sliding off a rock face.
 * docs/rover-model.md, "Loads". */
#include <math.h>

#include "idefix.h"

const double SIDE_X[N_WHEELS] = {1.0, 1.0, -1.0, -1.0};  /* FL FR RL RR: front +1 */
const double SIDE_Y[N_WHEELS] = {1.0, -1.0, 1.0, -1.0};  /* left +1 */

/* Statics of a rigid chassis on four compliant supports (any text on statically indeterminate
 * supports, e.g. Timoshenko & Young, Engineering Mechanics; for vehicles the axle loads of
 * Wong, Theory of Ground Vehicles). The normal loads W_i must balance the weight's normal component
 * and its moments: sum W_i = m g_z, sum W_i x_i = m g_x h, sum W_i y_i = m g_y h (moments
 * about the point of the contact plane under the centre of gravity; the in-plane forces act in
 * that plane), with (x_i, y_i) the body-frame point where the ground's force acts on wheel i.
 *
 * On soil that point is under the hub. On a rock it is the contact point, e_i = r sin(alpha_i)
 * ahead of the hub (alpha_i the contact angle from the body normal): the wheel and its axle,
 * held by the motor, pass the contact force to the chassis as a force at the hub plus the
 * motor's reaction torque, which together are the contact force at the contact point. The
 * rock's push along the plane, acting r (1 - cos alpha) above the wheel's lowest point, is an
 * in-plane force like the others and its moment is not included.
 *
 * Four supports leave one load pattern n free (sum n_i = 0, sum n_i x_i = 0, sum n_i y_i = 0).
 * With the static shares S_i (the rectangle of hubs, the reference the supports are deflected
 * by), the loads are W = S + q + t n: q = s_x k restores the moment the shifted supports take
 * from S, and t follows from compatibility. The support heights h_i (the undisturbed soil
 * surface under a soil wheel, the wheel's lowest point on a rock) need not lie in a plane;
 * their twist w = sum s_i h_i / 4 (s_i = s_x s_y: +1 for FL and RR, -1 for FR and RL; zero for
 * any plane through the hubs, where the legs deflect) is taken up by the supports' deflections
 * c_i (W_i - S_i):
 * sum s_i c_i (q_i + t n_i) = 4 w, with c_i = c_leg + z_i / ((n + 1/2) S_i) the leg's compliance
 * (rover.leg_compliance) in series with that of a Bekker wheel (W grows as z^(n+1/2)), 0 on a
 * rock. With every support under its hub n = s and q = 0: T = 4 w / sum c_i, one diagonal
 * gaining what the other loses.
 *
 * The heights are those of the supports carrying S_i undeflected, one datum for both kinds: a
 * rock support is rigid, so its height is the rim's lowest point; a soil support carrying S_i
 * holds the rim at the static sinkage of S_i below the undisturbed surface (linearising the
 * soil's deflection about S_i: z(W) = z(S) + z'(S) (W - S), the compliance above). Counting a
 * soil support from the surface instead made a rock flush with a wheel's rim, which changes no
 * load, twist the chassis by that wheel's static sinkage.
 *
 * Supports push and never pull: t is bounded where a load reaches 0, and the chassis then
 * rests on three wheels, whose loads the three balances give uniquely. A wheel sliding off a
 * rock face (`dropping`) carries the least load these bounds allow: none when the other three
 * can carry the chassis. Several sliding at once carry the least loads in the least-squares
 * sense (continuous where their offsets cancel). */

/* Per wheel: the support's offset ahead of the hub, its height and its compliance. */
static void supports(const Instance *inst, const double contact_angle[N_WHEELS], double plane_x,
                     double offset[N_WHEELS], double height[N_WHEELS],
                     double compliance[N_WHEELS])
{
    const double radius = inst->r[VR_ROVER_WHEEL_RADIUS], width = inst->r[VR_ROVER_WHEEL_WIDTH];
    int i;
    for (i = 0; i < N_WHEELS; i++) {
        const Wheel *w = &inst->wheels[i];
        offset[i] = w->on_rock ? radius * sin(contact_angle[i] - atan(plane_x)) : 0.0;
        /* undeflected under its static share (w->load here): on a rock the rim's lowest point;
         * on soil the static sinkage of the share below the undisturbed surface, which the
         * centre stands its supporting depth below */
        height[i] = w->centre_z - radius;
        compliance[i] = inst->r[VR_ROVER_LEG_COMPLIANCE];
        if (!w->on_rock) {
            double static_sinkage = bekker_static_sinkage(&inst->soil, w->load, radius, width);
            height[i] += w->support_sinkage - static_sinkage;
            if (w->load > 0.0)
                compliance[i] += static_sinkage / ((inst->soil.n + 0.5) * w->load);
        }
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
    double gx, gy, gz, offset[N_WHEELS], height[N_WHEELS], compliance[N_WHEELS];
    double arm = 4.0 * hw, shift = 0.0, skew = 0.0, twist = 0.0, rhs, stiffness = 0.0;
    double q[N_WHEELS], n[N_WHEELS], base[N_WHEELS], t, t_lo = -1e300, t_hi = 1e300;
    double dropping_slope = 0.0;  /* d/dt of the sliding wheels' total load */
    double dropping_moment = 0.0, dropping_norm = 0.0;  /* sum b n, sum n^2 over them */
    int dropping_count = 0;
    int i, lo = -1, hi = -1;  /* the wheels whose loads reach 0 at t_lo, t_hi */

    /* gravity in the body frame, R = Rz(yaw) Ry(pitch) Rx(roll), z up */
    gx = g * sin(inst->pitch);
    gy = -g * sin(inst->roll) * cos(inst->pitch);
    gz = g * cos(inst->pitch) * cos(inst->roll);

    /* static shares on the rectangle of hubs: the load transfer of the in-plane gravity */
    for (i = 0; i < N_WHEELS; i++) {
        double load = mass * gz / 4.0 + SIDE_X[i] * mass * gx * cog / (4.0 * hw) +
                      SIDE_Y[i] * mass * gy * cog / (4.0 * ht);
        inst->wheels[i].load = load > 0.0 ? load : 0.0;
    }
    supports(inst, contact_angle, plane_x, offset, height, compliance);

    /* q = s_x k: sum q x = -sum S e (the moment lost by moving the supports); n = s - s_x beta */
    for (i = 0; i < N_WHEELS; i++) {
        arm += SIDE_X[i] * offset[i];
        shift += inst->wheels[i].load * offset[i];
        skew += SIDE_X[i] * SIDE_Y[i] * offset[i];
        twist += 0.25 * SIDE_X[i] * SIDE_Y[i] * height[i];
    }
    rhs = 4.0 * twist;
    for (i = 0; i < N_WHEELS; i++) {
        double sign = SIDE_X[i] * SIDE_Y[i];
        q[i] = -SIDE_X[i] * shift / arm;
        n[i] = sign - SIDE_X[i] * skew / arm;
        base[i] = inst->wheels[i].load + q[i];
        rhs -= sign * compliance[i] * q[i];
        stiffness += sign * compliance[i] * n[i];
    }
    /* compatibility; rigid supports (no compliance) take the twist at the bound below */
    if (stiffness > 0.0) t = rhs / stiffness;
    else t = rhs > 0.0 ? 1e300 : (rhs < 0.0 ? -1e300 : 0.0);

    /* the range of t over which no support pulls */
    for (i = 0; i < N_WHEELS; i++) {
        if (n[i] > 0.0 && -base[i] / n[i] > t_lo) {
            t_lo = -base[i] / n[i];
            lo = i;
        }
        if (n[i] < 0.0 && -base[i] / n[i] < t_hi) {
            t_hi = -base[i] / n[i];
            hi = i;
        }
    }

    /* A wheel on the far side of a rock, on a face steeper than the friction cone of the
     * contact (atan mu) in its direction of travel, cannot rest on it: it slides off and drops
     * (slowly in milli-g), the chassis rocking onto the other wheels as far as they can carry
     * it, instead of a face that could carry it only by pushing the rover on. */
    for (i = 0; i < N_WHEELS; i++) {
        Wheel *w = &inst->wheels[i];
        double dir = w->rate > 0.0 ? 1.0 : (w->rate < 0.0 ? -1.0 : (inst->u >= 0.0 ? 1.0 : -1.0));
        w->dropping = w->on_rock && dir * (contact_angle[i] - atan(plane_x)) < -atan(mu);
        if (w->dropping) {
            dropping_slope += n[i];
            dropping_moment += base[i] * n[i];
            dropping_norm += n[i] * n[i];
            dropping_count++;
        }
    }
    /* One sliding wheel goes to the bound where its load vanishes. Several share the least
     * loads the bounds allow in the least-squares sense, t = -sum b n / sum n^2 (then clamped):
     * continuous in the geometry. Choosing the bound by the sign of their summed slope, which
     * nearly cancels when their offsets do, let rounding pick which of them carried nothing
     * (across a ridge under both front wheels, a 1e-9 m start offset moved the end by 5.2 mm). */
    if (dropping_count >= 2 && dropping_norm > 0.0) t = -dropping_moment / dropping_norm;
    else if (dropping_slope != 0.0) t = dropping_slope > 0.0 ? t_lo : t_hi;

    /* within the range (where it is empty the chassis tips: outside this model, loads >= 0) */
    t = t < t_lo ? t_lo : t;
    t = t > t_hi ? t_hi : t;
    for (i = 0; i < N_WHEELS; i++) {
        double load = base[i] + t * n[i];
        inst->wheels[i].load = load > 0.0 ? load : 0.0;
    }
    /* At a bound the chassis rests on three wheels and the fourth carries nothing: exactly 0,
     * not the rounding residue of base + t n (a few 1e-18 N), which would count as a load
     * (a loaded wheel presses and marks the soil; one at 0 is lifted). */
    if (t == t_lo && lo >= 0) inst->wheels[lo].load = 0.0;
    if (t == t_hi && hi >= 0) inst->wheels[hi].load = 0.0;
    inst->gx = gx;
    inst->gy = gy;
}
