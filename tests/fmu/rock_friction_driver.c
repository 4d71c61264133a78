/* Forces of one wheel on a rock (wheel.c, wheel_forces) for the statics test of
 * test_fmu_rock_climb.py: a wheel of load W with its contact tilted by `angle` in the wheel
 * plane, sliding with rim speed `rim` against a path speed `along` and a sideways speed `vy`.
 * The other wheels can push it with at most `push` (their strength).
 * usage: rock_friction_driver angle load rim along vy push; prints fx fy thrust. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <math.h>

#include "idefix.h"

int main(int argc, char **argv)
{
    Wheel w;
    double angle, along, fx, fy, thrust;
    const double radius = 0.1;
    if (argc != 7) return 2;
    memset(&w, 0, sizeof w);
    angle = atof(argv[1]);
    w.load = atof(argv[2]);
    w.rate = atof(argv[3]) / radius;
    along = atof(argv[4]);
    w.on_rock = 1;
    w.grade = angle;
    w.path_angle = angle;
    w.capacity = 0.6 * w.load;     /* rock.friction_coefficient x load, as wheel_ground_state */
    w.contact_length = 0.02;       /* rock.contact_length */
    w.shear_K = 0.001;             /* rock.shear_K */
    w.push_limit = atof(argv[6]);
    /* the body's speed that moves the hub along its path at `along`, and sideways at vy */
    wheel_forces(&w, radius, 0.6, along * cos(angle), atof(argv[5]), 0.0, 1e-5, &fx, &fy,
                 &thrust);
    printf("%.17g %.17g %.17g\n", fx, fy, thrust);
    return 0;
}
