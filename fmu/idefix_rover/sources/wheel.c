/* Wheel-ground contact: forces of one wheel for a given body velocity (docs/rover-model.md,
 * section "Wheel-ground contact"). Geometry and soil state were set by rover.c for this step. */
#include <math.h>

#include "idefix.h"

#define WALL_DAMPING 1e6   /* N/(m/s): a rock face above the axle stops the wheel */
#define PATH_COS_FLOOR 1e-3 /* numerical guard of v_x / cos(alpha) for a contact at the axle */

/* Speed of the wheel centre along its path from its body-plane speed v_x. On a rock the hub
 * turns about the contact (rolling or sliding on it, it stays a radius from it), so it moves
 * along the contact's tangent, at the contact angle alpha to the horizontal: its horizontal
 * speed v_x cos(pitch) is that speed times cos(alpha) (the wheel-centre velocity of rough-
 * terrain wheel kinematics is parallel to the terrain tangent at the contact: Iagnemma &
 * Dubowsky 2000, Lamon & Siegwart 2005). Slip and the rock's friction are measured along that
 * path. On soil the DEM's grade at the wheel centre is no contact angle (docs/rover-model.md,
 * "Wheel-ground contact"): v_x itself. */
double wheel_path_speed(const Wheel *w, double vx)
{
    double c;
    if (!w->on_rock) return vx;
    c = cos(w->path_angle);
    return vx * cos(w->pitch) / (c > PATH_COS_FLOOR ? c : PATH_COS_FLOOR);
}

void wheel_forces(Wheel *w, double radius, double rock_mu, double u, double v, double omega,
                  double v_eps, double *fx, double *fy, double *thrust)
{
    /* contact-point velocity over ground, body frame; along: the hub's speed along its path */
    double vx = u - omega * w->py, vy = v + omega * w->px;
    double along = wheel_path_speed(w, vx);
    double rim = radius * w->rate;
    /* sliding velocity of the rim relative to the ground (positive x: wheel spins ahead) */
    double sx = rim - along, sy = -vy;
    double sliding = sqrt(sx * sx + sy * sy);
    double ground = sqrt(along * along + vy * vy);
    double reference = (fabs(rim) > ground ? fabs(rim) : ground) + v_eps;
    /* shear displacement at the rear of the patch: patch length times the slip */
    double j = w->contact_length * sliding / reference;
    double mobilised = w->capacity * janosi_mobilisation(j, w->shear_K);
    double norm = sqrt(sliding * sliding + v_eps * v_eps);
    double tx = mobilised * sx / norm, ty = mobilised * sy / norm;
    double rolling = tanh(vx / v_eps);
    double force_x;

    if (w->on_rock) {
        /* rigid contact with normal tilted by the grade a: F = W tan(atan(mu_m) - a) */
        /* N cos a + T sin a = W and T = m mu N give F_x = W tan(atan(m mu) - a); beyond a
         * right angle the contact cannot carry the wheel at any push: a near-rigid stop. */
        double load = w->load > 1e-12 ? w->load : 1e-12;
        double friction_angle = atan(tx / load);  /* atan(m mu) */
        double angle = friction_angle - w->grade;
        const double limit = 0.5 * 3.141592653589793 - 0.01;
        angle = angle > limit ? limit : (angle < -limit ? -limit : angle);
        force_x = load * tan(angle);
        /* Coulomb friction acts on the contact's normal force N, not on the load W: along the
         * face (the rim's torque) and across the wheel, T = m mu N with N = W / (cos a + m mu
         * sin a) = W cos(atan(m mu)) / cos(atan(m mu) - a) from the same balance (the lateral
         * friction lies in the tangent plane and carries no weight). `mobilised` was taken of
         * mu W: scale by N / W. The contact's force in the wheel plane, W / cos(angle), is
         * that of a wheel whose weight the face carries; near the stop it grows without bound,
         * but no face pushes back harder than the rover pushes the wheel into it: at most the
         * other wheels' strength (w->push_limit), so N is at most cos(atan(m mu)) sqrt(W^2 +
         * P^2). */
        {
            double contact = load / cos(angle);
            double most = sqrt(load * load + w->push_limit * w->push_limit);
            double normal = cos(friction_angle) * (contact < most ? contact : most);
            ty *= normal / load;
            tx *= normal / load;
        }
        (void)rock_mu;
    } else {
        force_x = tx - w->load * tan(w->grade) - w->resistance * rolling;
        /* the passive wedge beside the wheel builds up with the soil's lateral displacement
         * over the patch, as the shear does (Wong & Chiang's lateral shear; Yu et al.'s
         * displacement-based lateral resistance), not at the first micrometre of sideways
         * motion: a wide arc barely pushes its ruts' walls */
        double lateral = w->contact_length * fabs(vy) / reference;
        ty -= w->bulldozing * janosi_mobilisation(lateral, w->shear_K) *
              vy / sqrt(vy * vy + v_eps * v_eps);
    }
    if (w->blocked && vx * w->blocked > 0.0) force_x -= WALL_DAMPING * vx;
    *fx = force_x;
    *fy = ty;
    *thrust = tx;
}

/* Ground state of wheel i for this step, from its load: on a rock the Coulomb contact; on soil
 * Bekker sinkage with slip sinkage, the rut under its patch, patch length, shear strength and
 * compaction resistance (docs/rover-model.md, "Soil"). */
void wheel_ground_state(Instance *inst, int i)
{
    const double radius = inst->r[VR_ROVER_WHEEL_RADIUS], width = inst->r[VR_ROVER_WHEEL_WIDTH];
    const SoilParameters *soil = &inst->soil;
    Wheel *w = &inst->wheels[i];
    double hx = cos(inst->yaw), hy = sin(inst->yaw);
    if (w->on_rock) {
        w->capacity = inst->r[VR_ROCK_FRICTION_COEFFICIENT] * w->load;
        w->contact_length = inst->r[VR_ROCK_CONTACT_LENGTH];
        w->shear_K = inst->r[VR_ROCK_SHEAR_K];
        w->resistance = 0.0;
        w->sinkage = 0.0;
        /* The rock holds the wheel as long as it holds it above the height at which the soil
         * alone would carry it there: the static sinkage of its load, or of its share of the
         * weight on four wheels where that is more (a wheel sliding off a rock's far side
         * carries almost nothing until the soil takes its share), or the floor of a rut it
         * would sink to, as on soil below (without slip's excavation, which a wheel on a rock
         * does not dig), and never less than the depth it had when it got onto the rock (its
         * load on the rock differs from its load on the soil, on a slope from that share, and
         * its sinkage there held slip's excavation: a shallower depth here would hand it back
         * to the soil at once). The soil's support is compared at that sinkage, not at the
         * rock's zero: with zero, a rim between the soil surface and that depth was on the
         * soil one step, sinking to it, and on the rock the next, every step
         * (docs/rover-model.md, "Rocks"). */
        {
            double share = 0.25 * inst->r[VR_ROVER_MASS] * inst->r[VR_ROVER_GRAVITY];
            double z0 = bekker_static_sinkage(soil, w->load > share ? w->load : share, radius,
                                              width);
            RutState under = soil_query(&inst->grid, w->wx, w->wy, hx, hy,
                                        sqrt(2.0 * radius * z0), width, i, w->travel,
                                        w->mark_span);
            double floor_depth = under.rut_depth + soil->multipass_factor * under.disturbed * z0;
            double support = z0 > floor_depth ? z0 : floor_depth;
            if (support < w->support_sinkage) support = w->support_sinkage;
            w->support_sinkage = support < soil->max_sinkage ? support : soil->max_sinkage;
        }
        w->rut_depth = 0.0;
        w->disturbed = 0.0;
        w->patch_length = 0.0;
        w->slip_excavation = 0.0;
        w->bulldozing = 0.0;
    } else {
        double z0 = bekker_static_sinkage(soil, w->load, radius, width);
        /* Slip digs the wheel in (Lyasko's steady slip sinkage), but only as the rim moves the
         * soil: the excavation approaches its steady value over one patch length of travel and
         * fills in again the same way on fresh soil. */
        double target = slip_sinkage(z0, w->slip) - z0;
        double relax = w->patch_length > 0.0 ? w->patch_length : sqrt(2.0 * radius * z0);
        double zs, patch, cohesion, rut_floor, floor_length, pressed;
        RutState rut;
        if (relax > 0.0)
            w->slip_excavation += (target - w->slip_excavation) * (1.0 - exp(-w->step_travel / relax));
        zs = z0 + w->slip_excavation;
        if (zs > soil->max_sinkage) zs = soil->max_sinkage;
        patch = sqrt(2.0 * radius * zs);
        /* the cells of the wheel's own moving patch are those it marked within the extent of
         * the patch that marked them; a wheel that made no mark last step (lifted, or on a
         * rock) has no patch of its own now, and its present one must not decide which of its
         * old marks are still "own": that fed back (rut seen -> patch -> own -> no rut -> no
         * patch -> rut seen) into a period-two flicker of a lifted wheel's sinkage */
        rut = soil_query(&inst->grid, w->wx, w->wy, hx, hy, patch, width, i, w->travel,
                         w->marked ? w->own_span + w->patch_length : w->mark_span);
        cohesion = soil->cohesion * (1.0 - rut.disturbed * (1.0 - soil->rut_cohesion_factor));
        /* multi-pass: a wheel in a rut sinks on by a fraction of its first-pass sinkage */
        rut_floor = rut.rut_depth + soil->multipass_factor * rut.disturbed * zs;
        w->rut_depth = rut.rut_depth;
        w->disturbed = rut.disturbed;
        w->sinkage = zs > rut_floor ? zs : rut_floor;
        if (w->sinkage > soil->max_sinkage) w->sinkage = soil->max_sinkage;
        w->support_sinkage = w->sinkage;
        w->patch_length = sqrt(2.0 * radius * w->sinkage);
        /* The soil's strength acts on the patch the wheel presses: in a rut, the arc of the
         * rim below the rut's floor, where the compaction resistance acts too (above the floor
         * the rim faces the groove the wheel ahead left; a soil point takes stress only where
         * the wheel is below its deformed level, as in Chrono's SCM); a lifted wheel (load 0,
         * no static sinkage) presses only what its slip's excavation still holds it in, which
         * fills in over a patch length of travel. The shear displacement builds up over that
         * arc, and over at least the length the grousers engage, a patch as deep as they are
         * tall, however firm the soil. */
        pressed = w->sinkage > rut.rut_depth ? sqrt(2.0 * radius * (w->sinkage - rut.rut_depth))
                                             : 0.0;
        floor_length = sqrt(2.0 * radius * inst->r[VR_ROVER_GROUSER_HEIGHT]);
        w->contact_length = pressed > floor_length ? pressed : floor_length;
        w->capacity = width * pressed * cohesion + w->load * tan(soil->friction_angle);
        w->shear_K = soil->K;
        w->resistance = compaction_resistance(soil, w->sinkage, rut.rut_depth, width);
        /* passive soil pressure beside the wheel: no more than the load that keeps it down (a
         * pushed wheel rides out of its rut rather than shear a wedge it cannot hold down) */
        w->bulldozing = lateral_bulldozing(soil, cohesion, w->patch_length, w->sinkage);
        if (w->bulldozing > w->load) w->bulldozing = w->load;
    }
}
