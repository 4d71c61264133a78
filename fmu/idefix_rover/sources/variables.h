/* Generated from idefix_rules/fmu/variables.py; do not edit by hand. */
#ifndef IDEFIX_VARIABLES_H
#define IDEFIX_VARIABLES_H

#define MAX_COMMANDS 32
#define N_REAL 174
#define VR_CHAIN_COUNT 0 /* Integer */
#define VR_TERRAIN_FILE 0 /* String */

/* Real value references */
#define VR_ROVER_MASS 0
#define VR_ROVER_GRAVITY 1
#define VR_ROVER_WHEEL_RADIUS 2
#define VR_ROVER_WHEEL_WIDTH 3
#define VR_ROVER_HALF_TRACK 4
#define VR_ROVER_HALF_WHEELBASE 5
#define VR_ROVER_YAW_INERTIA 6
#define VR_ROVER_COG_HEIGHT 7
#define VR_ROVER_GROUSER_HEIGHT 8
#define VR_ROVER_LEG_COMPLIANCE 9
#define VR_ROVER_BODY_CENTRE_HEIGHT 10
#define VR_SOIL_K_C 11
#define VR_SOIL_K_PHI 12
#define VR_SOIL_N 13
#define VR_SOIL_COHESION 14
#define VR_SOIL_FRICTION_ANGLE 15
#define VR_SOIL_SHEAR_MODULUS_K 16
#define VR_SOIL_RUT_COHESION_FACTOR 17
#define VR_SOIL_MULTIPASS_FACTOR 18
#define VR_SOIL_REFERENCE_GRAVITY 19
#define VR_SOIL_REFERENCE_COHESION 20
#define VR_SOIL_MAX_SINKAGE 21
#define VR_SOIL_GRID_CELL 22
#define VR_ROCK_FRICTION_COEFFICIENT 23
#define VR_ROCK_SHEAR_K 24
#define VR_ROCK_CONTACT_LENGTH 25
#define VR_MOTOR_NO_LOAD_CURRENT 26
#define VR_MOTOR_TORQUE_CONSTANT 27
#define VR_MOTOR_MAX_TORQUE 28
#define VR_CONTROLLER_WHEEL_ACCELERATION 29
#define VR_CONTROLLER_TIMEOUT_FACTOR 30
#define VR_CONTROLLER_STUCK_TIME 31
#define VR_CONTROLLER_STUCK_PROGRESS 32
#define VR_CONTROLLER_HEADING_FEEDBACK 33
#define VR_CONTROLLER_HEADING_GAIN 34
#define VR_CONTROLLER_HEADING_TOLERANCE 35
#define VR_CONTROLLER_RATE_FLOOR 36
#define VR_GYRO_BIAS 37
#define VR_GYRO_SCALE_ERROR 38
#define VR_INITIAL_X 39
#define VR_INITIAL_Y 40
#define VR_INITIAL_YAW 41
#define VR_SOLVER_STEP 42
#define VR_SOLVER_VELOCITY_EPSILON 43
#define VR_CHAIN_MAX_WHEEL_RATE 44
#define VR_CHAIN_DELTA_POSITION 76
#define VR_CHAIN_DELTA_HEADING 108
#define VR_T 140
#define VR_X 141
#define VR_Y 142
#define VR_Z 143
#define VR_ROLL 144
#define VR_PITCH 145
#define VR_YAW 146
#define VR_WHEEL_FL_RATE 147
#define VR_WHEEL_FR_RATE 148
#define VR_WHEEL_RL_RATE 149
#define VR_WHEEL_RR_RATE 150
#define VR_WHEEL_FL_SLIP 151
#define VR_WHEEL_FR_SLIP 152
#define VR_WHEEL_RL_SLIP 153
#define VR_WHEEL_RR_SLIP 154
#define VR_WHEEL_FL_SLIP_ANGLE 155
#define VR_WHEEL_FR_SLIP_ANGLE 156
#define VR_WHEEL_RL_SLIP_ANGLE 157
#define VR_WHEEL_RR_SLIP_ANGLE 158
#define VR_WHEEL_FL_SINKAGE 159
#define VR_WHEEL_FR_SINKAGE 160
#define VR_WHEEL_RL_SINKAGE 161
#define VR_WHEEL_RR_SINKAGE 162
#define VR_WHEEL_FL_CURRENT 163
#define VR_WHEEL_FR_CURRENT 164
#define VR_WHEEL_RL_CURRENT 165
#define VR_WHEEL_RR_CURRENT 166
#define VR_WHEEL_FL_LOAD 167
#define VR_WHEEL_FR_LOAD 168
#define VR_WHEEL_RL_LOAD 169
#define VR_WHEEL_RR_LOAD 170
#define VR_ENERGY 171
#define VR_COMMAND 172
#define VR_STUCK 173

/* per-wheel outputs: base + wheel index (FL, FR, RL, RR) */
#define VR_WHEEL_RATE 147
#define VR_WHEEL_SLIP 151
#define VR_WHEEL_SLIP_ANGLE 155
#define VR_WHEEL_SINKAGE 159
#define VR_WHEEL_CURRENT 163
#define VR_WHEEL_LOAD 167

/* start values of every Real, indexed by value reference */
#define REAL_DEFAULTS { \
    25.0, /* rover.mass */ \
    0.0057, /* rover.gravity */ \
    0.1, /* rover.wheel_radius */ \
    0.06, /* rover.wheel_width */ \
    0.26, /* rover.half_track */ \
    0.2, /* rover.half_wheelbase */ \
    1.0, /* rover.yaw_inertia */ \
    0.25, /* rover.cog_height */ \
    0.001, /* rover.grouser_height */ \
    0.03, /* rover.leg_compliance */ \
    0.3, /* rover.body_centre_height */ \
    1400.0, /* soil.k_c */ \
    820000.0, /* soil.k_phi */ \
    1.0, /* soil.n */ \
    250.0, /* soil.cohesion */ \
    0.6108652381980153, /* soil.friction_angle */ \
    0.012, /* soil.shear_modulus_K */ \
    0.5, /* soil.rut_cohesion_factor */ \
    0.3, /* soil.multipass_factor */ \
    1.62, /* soil.reference_gravity */ \
    170.0, /* soil.reference_cohesion */ \
    0.03, /* soil.max_sinkage */ \
    0.01, /* soil.grid_cell */ \
    0.6, /* rock.friction_coefficient */ \
    0.001, /* rock.shear_K */ \
    0.02, /* rock.contact_length */ \
    0.0003, /* motor.no_load_current */ \
    2.0, /* motor.torque_constant */ \
    0.2, /* motor.max_torque */ \
    0.015, /* controller.wheel_acceleration */ \
    2.0, /* controller.timeout_factor */ \
    10.0, /* controller.stuck_time */ \
    0.01, /* controller.stuck_progress */ \
    1.0, /* controller.heading_feedback */ \
    0.5, /* controller.heading_gain */ \
    0.003490658503988659, /* controller.heading_tolerance */ \
    0.5, /* controller.rate_floor */ \
    0.0, /* gyro.bias */ \
    0.0, /* gyro.scale_error */ \
    0.0, /* initial.x */ \
    0.0, /* initial.y */ \
    0.0, /* initial.yaw */ \
    0.05, /* solver.step */ \
    1e-05, /* solver.velocity_epsilon */ \
    0.0, /* chain.max_wheel_rate[0] */ \
    0.0, /* chain.max_wheel_rate[1] */ \
    0.0, /* chain.max_wheel_rate[2] */ \
    0.0, /* chain.max_wheel_rate[3] */ \
    0.0, /* chain.max_wheel_rate[4] */ \
    0.0, /* chain.max_wheel_rate[5] */ \
    0.0, /* chain.max_wheel_rate[6] */ \
    0.0, /* chain.max_wheel_rate[7] */ \
    0.0, /* chain.max_wheel_rate[8] */ \
    0.0, /* chain.max_wheel_rate[9] */ \
    0.0, /* chain.max_wheel_rate[10] */ \
    0.0, /* chain.max_wheel_rate[11] */ \
    0.0, /* chain.max_wheel_rate[12] */ \
    0.0, /* chain.max_wheel_rate[13] */ \
    0.0, /* chain.max_wheel_rate[14] */ \
    0.0, /* chain.max_wheel_rate[15] */ \
    0.0, /* chain.max_wheel_rate[16] */ \
    0.0, /* chain.max_wheel_rate[17] */ \
    0.0, /* chain.max_wheel_rate[18] */ \
    0.0, /* chain.max_wheel_rate[19] */ \
    0.0, /* chain.max_wheel_rate[20] */ \
    0.0, /* chain.max_wheel_rate[21] */ \
    0.0, /* chain.max_wheel_rate[22] */ \
    0.0, /* chain.max_wheel_rate[23] */ \
    0.0, /* chain.max_wheel_rate[24] */ \
    0.0, /* chain.max_wheel_rate[25] */ \
    0.0, /* chain.max_wheel_rate[26] */ \
    0.0, /* chain.max_wheel_rate[27] */ \
    0.0, /* chain.max_wheel_rate[28] */ \
    0.0, /* chain.max_wheel_rate[29] */ \
    0.0, /* chain.max_wheel_rate[30] */ \
    0.0, /* chain.max_wheel_rate[31] */ \
    0.0, /* chain.delta_position[0] */ \
    0.0, /* chain.delta_position[1] */ \
    0.0, /* chain.delta_position[2] */ \
    0.0, /* chain.delta_position[3] */ \
    0.0, /* chain.delta_position[4] */ \
    0.0, /* chain.delta_position[5] */ \
    0.0, /* chain.delta_position[6] */ \
    0.0, /* chain.delta_position[7] */ \
    0.0, /* chain.delta_position[8] */ \
    0.0, /* chain.delta_position[9] */ \
    0.0, /* chain.delta_position[10] */ \
    0.0, /* chain.delta_position[11] */ \
    0.0, /* chain.delta_position[12] */ \
    0.0, /* chain.delta_position[13] */ \
    0.0, /* chain.delta_position[14] */ \
    0.0, /* chain.delta_position[15] */ \
    0.0, /* chain.delta_position[16] */ \
    0.0, /* chain.delta_position[17] */ \
    0.0, /* chain.delta_position[18] */ \
    0.0, /* chain.delta_position[19] */ \
    0.0, /* chain.delta_position[20] */ \
    0.0, /* chain.delta_position[21] */ \
    0.0, /* chain.delta_position[22] */ \
    0.0, /* chain.delta_position[23] */ \
    0.0, /* chain.delta_position[24] */ \
    0.0, /* chain.delta_position[25] */ \
    0.0, /* chain.delta_position[26] */ \
    0.0, /* chain.delta_position[27] */ \
    0.0, /* chain.delta_position[28] */ \
    0.0, /* chain.delta_position[29] */ \
    0.0, /* chain.delta_position[30] */ \
    0.0, /* chain.delta_position[31] */ \
    0.0, /* chain.delta_heading[0] */ \
    0.0, /* chain.delta_heading[1] */ \
    0.0, /* chain.delta_heading[2] */ \
    0.0, /* chain.delta_heading[3] */ \
    0.0, /* chain.delta_heading[4] */ \
    0.0, /* chain.delta_heading[5] */ \
    0.0, /* chain.delta_heading[6] */ \
    0.0, /* chain.delta_heading[7] */ \
    0.0, /* chain.delta_heading[8] */ \
    0.0, /* chain.delta_heading[9] */ \
    0.0, /* chain.delta_heading[10] */ \
    0.0, /* chain.delta_heading[11] */ \
    0.0, /* chain.delta_heading[12] */ \
    0.0, /* chain.delta_heading[13] */ \
    0.0, /* chain.delta_heading[14] */ \
    0.0, /* chain.delta_heading[15] */ \
    0.0, /* chain.delta_heading[16] */ \
    0.0, /* chain.delta_heading[17] */ \
    0.0, /* chain.delta_heading[18] */ \
    0.0, /* chain.delta_heading[19] */ \
    0.0, /* chain.delta_heading[20] */ \
    0.0, /* chain.delta_heading[21] */ \
    0.0, /* chain.delta_heading[22] */ \
    0.0, /* chain.delta_heading[23] */ \
    0.0, /* chain.delta_heading[24] */ \
    0.0, /* chain.delta_heading[25] */ \
    0.0, /* chain.delta_heading[26] */ \
    0.0, /* chain.delta_heading[27] */ \
    0.0, /* chain.delta_heading[28] */ \
    0.0, /* chain.delta_heading[29] */ \
    0.0, /* chain.delta_heading[30] */ \
    0.0, /* chain.delta_heading[31] */ \
    0.0, /* t */ \
    0.0, /* x */ \
    0.0, /* y */ \
    0.0, /* z */ \
    0.0, /* roll */ \
    0.0, /* pitch */ \
    0.0, /* yaw */ \
    0.0, /* wheel.FL.rate */ \
    0.0, /* wheel.FR.rate */ \
    0.0, /* wheel.RL.rate */ \
    0.0, /* wheel.RR.rate */ \
    0.0, /* wheel.FL.slip */ \
    0.0, /* wheel.FR.slip */ \
    0.0, /* wheel.RL.slip */ \
    0.0, /* wheel.RR.slip */ \
    0.0, /* wheel.FL.slip_angle */ \
    0.0, /* wheel.FR.slip_angle */ \
    0.0, /* wheel.RL.slip_angle */ \
    0.0, /* wheel.RR.slip_angle */ \
    0.0, /* wheel.FL.sinkage */ \
    0.0, /* wheel.FR.sinkage */ \
    0.0, /* wheel.RL.sinkage */ \
    0.0, /* wheel.RR.sinkage */ \
    0.0, /* wheel.FL.current */ \
    0.0, /* wheel.FR.current */ \
    0.0, /* wheel.RL.current */ \
    0.0, /* wheel.RR.current */ \
    0.0, /* wheel.FL.load */ \
    0.0, /* wheel.FR.load */ \
    0.0, /* wheel.RL.load */ \
    0.0, /* wheel.RR.load */ \
    0.0, /* energy */ \
    0.0, /* command */ \
    0.0, /* stuck */ \
}
#define FIRST_OUTPUT_VR 140

#endif
