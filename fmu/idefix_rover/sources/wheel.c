/* Wheel-ground contact: forces of one wheel for a given body velocity (docs/rover-model.md,
 * section "Wheel-ground contact"). Geometry and soil state were set by rover.c for this step. */
#include <math.h>

#include "idefix.h"

#define WALL_DAMPING 1e6   /* N/(m/s): a rock face above the axle stops the wheel */

void wheel_forces(Wheel *w, double radius, double rock_mu, double u, double v, double omega,
                  double v_eps, double *fx, double *fy, double *thrust)
{
    /* contact-point velocity over ground, body frame */
    double vx = u - omega * w->py, vy = v + omega * w->px;
    double rim = radius * w->rate;
    /* sliding velocity of the rim relative to the ground (positive x: wheel spins ahead) */
    double sx = rim - vx, sy = -vy;
    double sliding = sqrt(sx * sx + sy * sy);
    double ground = sqrt(vx * vx + vy * vy);
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
        double angle = atan(tx / load) - w->grade;
        const double limit = 0.5 * 3.141592653589793 - 0.01;
        angle = angle > limit ? limit : (angle < -limit ? -limit : angle);
        force_x = load * tan(angle);
        (void)rock_mu;
    } else {
        force_x = tx - w->load * tan(w->grade) - w->resistance * rolling;
    }
    if (w->blocked && vx * w->blocked > 0.0) force_x -= WALL_DAMPING * vx;
    *fx = force_x;
    *fy = ty;
    *thrust = tx;
}
