/* IDEFIX-like rover: shared types. All state lives in Instance; there are no globals. */
#ifndef IDEFIX_H
#define IDEFIX_H

#include <stddef.h>
#include "variables.h"

#define N_WHEELS 4
#define MAX_ROCKS 4096
#define MAX_GRID_CELLS 4000000L

/* ---------------------------------------------------------------- terrain.c */
typedef struct {
    double x, y, z;    /* ellipsoid centre, m (z above the terrain datum) */
    double a, b, c;    /* semi-axes along x, y, z, m (axis-aligned) */
} Rock;

typedef struct {
    int loaded;        /* 0: flat ground z = 0, no rocks */
    char *path;        /* file the data came from (cache key with the content hash) */
    unsigned long long hash;  /* FNV-1a of the file's bytes */
    long nx, ny;
    double x0, y0, cell;
    double *height;    /* ny rows of nx heights, row j at y0 + j*cell */
    int n_rocks;
    Rock *rocks;
    struct RockContact *contacts;  /* recent rock_wheel_centre answers (terrain.c), or NULL */
} Terrain;

int terrain_load(Terrain *t, const char *path, char *message, size_t message_size);
void terrain_free(Terrain *t);
double terrain_height(const Terrain *t, double x, double y);
/* Height of the highest rock surface at (x, y), or -1e300 if no rock is there. */
double rock_top(const Terrain *t, double x, double y);
/* Wheel-centre height needed to clear rock k (disc of radius r, width w, heading (hx, hy)).
 * Returns -1e300 when the rock is out of the wheel's reach. *contact_d: signed distance of the
 * contact ahead of the axle, *contact_z: height of the contact point. */
double rock_wheel_centre(const Terrain *t, int k, double x, double y, double hx, double hy,
                         double r, double w, double *contact_d, double *contact_z);

/* ---------------------------------------------------------------- soil.c */
typedef struct {
    double cell, x0, y0;
    long nx, ny;
    float *sinkage;          /* plastic sinkage (rut depth) averaged over the cell, m */
    float *coverage;         /* fraction of the cell the wheels' patches have run over */
    float *mark_travel;      /* distance its wheel had travelled when it last pressed it, m */
    unsigned char *owner;    /* wheel index + 1 that last ran over the cell, 0: undisturbed */
    float *prior_sinkage;    /* the cell as its last wheel found it: rut depth ... */
    float *prior_coverage;   /* ... and the fraction other wheels had run over */
    long dirty_i0, dirty_i1, dirty_j0, dirty_j1;   /* touched cells, cleared on reset */
} SoilGrid;

typedef struct {
    double k_c, k_phi, n, cohesion, friction_angle, K, rut_cohesion_factor, multipass_factor;
    double gravity, reference_gravity, reference_cohesion, max_sinkage;
} SoilParameters;

typedef struct {
    double rut_depth;        /* mean plastic sinkage under the patch, m */
    double disturbed;        /* fraction of the patch already sheared by a wheel */
} RutState;

int soil_grid_init(SoilGrid *g, double x_min, double y_min, double x_max, double y_max,
                   double cell);
void soil_grid_free(SoilGrid *g);
void soil_grid_clear(SoilGrid *g);
RutState soil_query(const SoilGrid *g, double cx, double cy, double hx, double hy, double length,
                    double width, int wheel, double travel, double own_span);
void soil_mark(SoilGrid *g, double cx, double cy, double hx, double hy, double length,
               double width, double sinkage, int wheel, double travel, double own_span);
double bekker_static_sinkage(const SoilParameters *s, double load, double radius, double width);
double slip_sinkage(double static_sinkage, double slip);
double soil_modulus(const SoilParameters *s, double width);
double lateral_bulldozing(const SoilParameters *s, double cohesion, double length, double sinkage);
double compaction_resistance(const SoilParameters *s, double sinkage, double rut_depth,
                             double width);
double janosi_mobilisation(double displacement, double K);

/* ---------------------------------------------------------------- wheel.c */
typedef struct {
    /* geometry and soil state for the current step */
    double px, py;           /* position in the body frame, m */
    double wx, wy;           /* contact position in the world, m */
    double centre_z;         /* wheel-centre height, m */
    double grade;            /* local grade of the wheel path relative to the body plane, rad */
    double path_angle;       /* the same path's angle to the horizontal (world), rad */
    double pitch;            /* the body's pitch when the grade was taken, rad */
    int on_rock;
    int dropping;            /* on a rock face too steep to rest on: carries the least load
                              * the other wheels leave it */
    int blocked;             /* a rock face above the axle in the driving direction */
    double blocked_time;     /* how long the wheel has turned against a face without progress, s */
    double load;             /* normal load, N */
    double sinkage;          /* below the undisturbed surface, m */
    double support_sinkage;  /* the sinkage at which the soil alone would carry the wheel: its
                              * sinkage on soil; on a rock, the static sinkage of its load or
                              * share of the weight, or a rut's floor there, at least the depth
                              * it got onto the rock with, m */
    double contact_length;   /* length the shear displacement builds over (soil: at least the
                              * grousers'), m */
    double patch_length;     /* geometric patch length sqrt(2 r z) (ruts), m */
    double slip_excavation;  /* sinkage dug by slip so far, m (builds up over the rim's travel) */
    double step_travel;      /* rim or ground travel in the last step, whichever is longer, m */
    double bulldozing;       /* lateral (bulldozing) resistance of the soil beside the wheel, N */
    double capacity;         /* shear strength of the patch (soil) or mu*W (rock), N */
    double push_limit;       /* the most the other wheels can push this one with: the sum of
                              * their strengths, N (bounds a rock contact's normal force) */
    double shear_K;          /* m */
    double resistance;       /* compaction resistance, N */
    double rut_depth, disturbed;
    /* results of the force balance */
    double rate;             /* wheel angular rate, rad/s */
    double fx, fy;           /* force on the body from this wheel, body frame, N */
    double thrust;           /* shear force along the wheel rim (for the torque), N */
    double slip, slip_angle, current;
    double prev_centre_z;
    /* distance the contact travelled over ground (rut ownership), and where it was */
    double travel, own_span, last_wx, last_wy;
    double mark_span;        /* own_span + patch_length of the wheel's last mark, m */
    int travel_started;
    int marked;              /* the wheel marked the soil in the last step */
} Wheel;

double wheel_path_speed(const Wheel *w, double vx);
void wheel_forces(Wheel *w, double radius, double rock_mu, double u, double v, double omega,
                  double v_eps, double *fx, double *fy, double *thrust);

/* ---------------------------------------------------------------- controller.c */
typedef struct {
    int count;
    int active;              /* index of the active command, -1 when done */
    double elapsed;          /* time in the active command, s */
    double duration;         /* ideal duration of the active command, s */
    double target_angle;     /* fastest wheel's commanded rotation, rad */
    double angle;            /* fastest wheel's odometry in this command, rad */
    int fastest;             /* wheel index with the largest commanded rate */
    double rates[N_WHEELS];  /* commanded wheel rates, rad/s */
    double commanded_speed;  /* ideal body speed of the active command, m/s */
    double commanded_yaw_rate;
    double profile;          /* share of the commanded rates applied in the last step, 0..1 */
    double max_rate, delta_position, delta_heading;  /* the active command */
    double travel;           /* mean odometry of the left and right wheels in the command, m */
    double heading;          /* gyro yaw change in the command (bias and scale error), rad */
    int trimming;            /* closed loop: turning on the spot to the commanded heading */
    int settling;            /* closed loop, on the spot: within the tolerance, ramping to rest */
    double settle_sign;      /* the direction the wheels turned when settling began */
    double ramp_time;        /* extra time of the ramps over the ideal duration, s */
    int stalled[N_WHEELS];
    /* stuck observer: ring of progress samples */
    double window_progress, window_commanded;
    int stuck;
} Controller;

/* ---------------------------------------------------------------- instance */
typedef struct {
    char *instance_name;
    void (*logger)(void);    /* fmi2CallbackLogger, cast back before the call */
    void *env;               /* fmi2ComponentEnvironment */
    int logging;
    double r[N_REAL];        /* every Real: parameters and outputs, indexed by value reference */
    int chain_count;
    char *terrain_file;
    Terrain terrain;
    SoilGrid grid;
    SoilParameters soil;
    Wheel wheels[N_WHEELS];
    Controller ctrl;
    double time;
    double x, y, yaw, z, roll, pitch;
    double gx, gy;           /* in-plane gravity, body frame, m/s^2 */
    double u, v, omega;      /* body velocity in the body plane (warm start) */
    double energy;
    int sliding;             /* no quasi-static balance in the last step: uncontrolled slide */
    int initialised;
} Instance;

void controller_start(Instance *inst);
void controller_step(Instance *inst, double dt);
void controller_after_step(Instance *inst, double dt, double progress, double yaw_rate);

/* ---------------------------------------------------------------- wheel.c (ground state) */
void wheel_ground_state(Instance *inst, int i);

/* ---------------------------------------------------------------- contact.c */
void contact_wheel_position(const Instance *inst, double x, double y, double yaw, const Wheel *w,
                            double *wx, double *wy);
void contact_update(Instance *inst, double contact_angle[N_WHEELS], double soil_slope[N_WHEELS]);
void contact_update_blocking(Instance *inst);
int contact_penetrating_wheel(const Instance *inst, const double prev_centre[N_WHEELS]);
int contact_push_out(Instance *inst, int i, const double prev_centre[N_WHEELS], double reach);

/* ---------------------------------------------------------------- loads.c */
extern const double SIDE_X[N_WHEELS], SIDE_Y[N_WHEELS];
void loads_update(Instance *inst, const double contact_angle[N_WHEELS]);

/* ---------------------------------------------------------------- balance.c */
void balance_residual(Instance *inst, const double q[3], double gx, double gy, double out[3]);
int balance_can_hold(const Instance *inst);
int balance_solve(Instance *inst, double gx, double gy, double q[3], int from_rest);
void balance_integrate(Instance *inst, double gx, double gy, const double previous[3], double dt,
                       double q[3]);
void balance_limit_acceleration(Instance *inst, const double previous[3], double q[3], double dt);

/* ---------------------------------------------------------------- parameters.c */
int parameters_check(const Instance *inst, char *message, size_t message_size);

/* ---------------------------------------------------------------- rover.c */
int rover_initialise(Instance *inst, char *message, size_t message_size);
void rover_step(Instance *inst, double dt);
void rover_write_outputs(Instance *inst);

#endif
