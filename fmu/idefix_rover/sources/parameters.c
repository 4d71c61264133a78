/* Parameter ranges checked at the end of initialisation (docs/rover-model.md, "Parameters"). */
#include <math.h>
#include <stdio.h>

#include "idefix.h"

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
    {VR_ROVER_LEG_COMPLIANCE, "rover.leg_compliance", 0.0, 1e3, 0, 0},
    {VR_ROVER_BODY_CENTRE_HEIGHT, "rover.body_centre_height", 0.0, 10.0, 0, 0},
    {VR_SOIL_K_C, "soil.k_c", 0.0, 1e9, 0, 0},
    {VR_SOIL_K_PHI, "soil.k_phi", 0.0, 1e12, 0, 0},
    {VR_SOIL_N, "soil.n", 0.0, 2.5, 0, 1},
    {VR_SOIL_COHESION, "soil.cohesion", 0.0, 1e6, 0, 0},
    {VR_SOIL_FRICTION_ANGLE, "soil.friction_angle", 0.0, 1.3962634015954636, 0, 0},  /* 80 deg */
    {VR_SOIL_SHEAR_MODULUS_K, "soil.shear_modulus_K", 0.0, 1.0, 1, 0},
    {VR_SOIL_RUT_COHESION_FACTOR, "soil.rut_cohesion_factor", 0.0, 1.0, 0, 0},
    {VR_SOIL_MULTIPASS_FACTOR, "soil.multipass_factor", 0.0, 2.0, 0, 0},
    {VR_SOIL_REFERENCE_GRAVITY, "soil.reference_gravity", 0.0, 30.0, 1, 0},
    {VR_SOIL_REFERENCE_COHESION, "soil.reference_cohesion", 0.0, 1e6, 0, 0},
    {VR_SOIL_MAX_SINKAGE, "soil.max_sinkage", 0.0, 1.0, 1, 0},
    {VR_ROVER_GROUSER_HEIGHT, "rover.grouser_height", 0.0, 0.1, 0, 0},
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
    {VR_CONTROLLER_HEADING_FEEDBACK, "controller.heading_feedback", 0.0, 1.0, 0, 0},
    {VR_CONTROLLER_HEADING_GAIN, "controller.heading_gain", 0.0, 100.0, 0, 0},
    {VR_CONTROLLER_HEADING_TOLERANCE, "controller.heading_tolerance", 0.0, 1.0, 1, 0},
    {VR_CONTROLLER_RATE_FLOOR, "controller.rate_floor", 0.0, 1.0, 0, 0},
    {VR_GYRO_BIAS, "gyro.bias", -1.0, 1.0, 0, 0},
    {VR_GYRO_SCALE_ERROR, "gyro.scale_error", -0.5, 0.5, 0, 0},
    {VR_INITIAL_X, "initial.x", -1e6, 1e6, 0, 0},
    {VR_INITIAL_Y, "initial.y", -1e6, 1e6, 0, 0},
    {VR_INITIAL_YAW, "initial.yaw", -1e6, 1e6, 0, 0},
    {VR_SOLVER_STEP, "solver.step", 0.0, 1.0, 1, 0},
    {VR_SOLVER_VELOCITY_EPSILON, "solver.velocity_epsilon", 0.0, 1e-3, 1, 0},
};

/* Every parameter in its range, else a message naming it, its value and the range. */
int parameters_check(const Instance *inst, char *message, size_t message_size)
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
    if (inst->r[VR_CONTROLLER_HEADING_FEEDBACK] != 0.0 &&
        inst->r[VR_CONTROLLER_HEADING_FEEDBACK] != 1.0) {
        snprintf(message, message_size, "parameter controller.heading_feedback = %.17g out of "
                 "range: allowed 0 (odometry) or 1 (gyro)", inst->r[VR_CONTROLLER_HEADING_FEEDBACK]);
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
