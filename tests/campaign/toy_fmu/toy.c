/* A toy rover FMU for the campaign tests: ideal arc kinematics with a fixed slip, plus faults
 * on demand (segfault, endless loop, FMI error or fatal error at a given time; an endless loop
 * leaving initialisation). FMI 2.0
 * co-simulation.
 * Value references come from toy_vr.h, written by the tests next to this file. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "fmi2Functions.h"
#include "toy_vr.h"

typedef struct {
    double r[N_REAL];
    int count;
    double time;
    double cmd_time;
    int cmd;
    int failed; /* a step returned fmi2Error or fmi2Fatal: only a reset or a free is allowed */
    const fmi2CallbackFunctions *cb;
} Toy;

/* Shared by every instance in the process, as a real FMU's global tables are, so that the fatal
 * fault can do what fmi2Fatal announces: it corrupts this, and every later step of any instance
 * in the process then slips more than its parameter says, with no error. */
static double shared_slip_error = 0.0;

static void reset_state(Toy *m) {
    memset(m->r, 0, sizeof(m->r));
    m->r[VR_SLIP] = 0.1;
    m->count = 0;
    m->time = 0.0;
    m->cmd_time = 0.0;
    m->cmd = 0;
    m->failed = 0;
}

fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid,
                              fmi2String location, const fmi2CallbackFunctions *cb,
                              fmi2Boolean visible, fmi2Boolean logging) {
    Toy *m = (Toy *)calloc(1, sizeof(Toy));
    (void)name; (void)type; (void)guid; (void)location; (void)visible; (void)logging;
    m->cb = cb;
    reset_state(m);
    return m;
}

void fmi2FreeInstance(fmi2Component c) { free(c); }
fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean a, fmi2Real tol, fmi2Real t0,
                               fmi2Boolean b, fmi2Real t1) {
    (void)a; (void)tol; (void)b; (void)t1;
    ((Toy *)c)->time = t0;
    return fmi2OK;
}
fmi2Status fmi2EnterInitializationMode(fmi2Component c) { (void)c; return fmi2OK; }
fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    Toy *m = (Toy *)c;
    const char *log = getenv("TOY_SETUP_LOG");
    if (log != NULL) {
        FILE *f = fopen(log, "a");
        if (f != NULL) { fputs("set up\n", f); fclose(f); }
    }
    if (m->r[VR_HANG_SETUP] > 0.0) {
        volatile int spin = 1;
        while (spin) { }
    }
    m->r[VR_X] = m->r[VR_INITIAL_X];
    m->r[VR_Y] = m->r[VR_INITIAL_Y];
    m->r[VR_YAW] = m->r[VR_INITIAL_YAW];
    m->r[VR_COMMAND] = m->count > 0 ? 0.0 : -1.0;
    return fmi2OK;
}
/* After an error only fmi2Reset and fmi2FreeInstance are allowed (FMI 2.0.x section 2.1.3):
 * the toy answers fmi2Terminate then with fmi2Error, as FMI 3.0 requires of a call its state
 * does not allow. */
fmi2Status fmi2Terminate(fmi2Component c) { return ((Toy *)c)->failed ? fmi2Error : fmi2OK; }
fmi2Status fmi2Reset(fmi2Component c) {
    Toy *m = (Toy *)c;
    double above = m->r[VR_RESET_FAILS_ABOVE], slip = m->r[VR_SLIP];
    const char *status = getenv("TOY_RESET_STATUS");
    if (above > 0.0 && slip > above) {  /* what the previous run left: the reset fails */
        if (status != NULL && status[0] == '3') { m->failed = 1; return fmi2Error; }
        shared_slip_error = 0.3;
        return fmi2Fatal;
    }
    reset_state(m);
    return fmi2OK;
}

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real v[]) {
    Toy *m = (Toy *)c;
    for (size_t i = 0; i < n; i++) v[i] = vr[i] == VR_T ? m->time : m->r[vr[i]];
    return fmi2OK;
}
fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                       const fmi2Real v[]) {
    Toy *m = (Toy *)c;
    for (size_t i = 0; i < n; i++) if (vr[i] < N_REAL) m->r[vr[i]] = v[i];
    return fmi2OK;
}
fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                          fmi2Integer v[]) {
    for (size_t i = 0; i < n; i++) v[i] = ((Toy *)c)->count;
    (void)vr;
    return fmi2OK;
}
fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                          const fmi2Integer v[]) {
    (void)vr;
    for (size_t i = 0; i < n; i++) ((Toy *)c)->count = v[i] > MAX_COMMANDS ? MAX_COMMANDS : v[i];
    return fmi2OK;
}
fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                          fmi2Boolean v[]) { (void)c; (void)vr; (void)n; (void)v; return fmi2OK; }
fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                          const fmi2Boolean v[]) { (void)c; (void)vr; (void)n; (void)v; return fmi2OK; }
static char terrain_file[1024];
fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                         fmi2String v[]) {
    (void)c; (void)vr;
    for (size_t i = 0; i < n; i++) v[i] = terrain_file;
    return fmi2OK;
}
fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                         const fmi2String v[]) {
    (void)c; (void)vr; (void)n; (void)v;
    return fmi2OK;
}

static double command_duration(Toy *m, int k) {
    double rate = fabs(m->r[VR_RATE0 + k]), dp = m->r[VR_DP0 + k], dh = m->r[VR_DH0 + k];
    double left = fabs(dp - HALF_TRACK * dh), right = fabs(dp + HALF_TRACK * dh);
    double fastest = left > right ? left : right;
    if (rate <= 0.0 || fastest <= 0.0) return 0.0;
    return fastest / (rate * WHEEL_RADIUS);
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean last) {
    Toy *m = (Toy *)c;
    double end = t + h, dt = 0.05;
    (void)last;
    while (m->time < end - 1e-12) {
        double step = end - m->time < dt ? end - m->time : dt;
        double now = m->time + step;
        if (m->r[VR_CRASH_AT] > 0.0 && now >= m->r[VR_CRASH_AT]) {
            volatile int *nowhere = NULL;
            *nowhere = 1;
        }
        if (m->r[VR_HANG_AT] > 0.0 && now >= m->r[VR_HANG_AT]) {
            volatile int spin = 1;
            while (spin) { }
        }
        if (m->r[VR_ERROR_AT] > 0.0 && now >= m->r[VR_ERROR_AT]) {
            m->failed = 1;
            return fmi2Error;
        }
        if (m->r[VR_NAN_AT] > 0.0 && now >= m->r[VR_NAN_AT]) m->r[VR_X] = NAN;
        if (m->r[VR_FATAL_AT] > 0.0 && now >= m->r[VR_FATAL_AT]) {
            char message[96];
            shared_slip_error = 0.3;
            m->failed = 1;
            /* the logger reads its format as the message: no conversion left in it */
            snprintf(message, sizeof(message), "toy: slip table corrupted at t = %g s", now);
            m->cb->logger(m->cb->componentEnvironment, "toy", fmi2Fatal, "logStatusFatal",
                          message);
            return fmi2Fatal;
        }
        double moving = 0.0;
        while (m->cmd < m->count) {
            double duration = command_duration(m, m->cmd);
            if (m->cmd_time < duration) {
                double slip = m->r[VR_SLIP] + shared_slip_error;
                double v = m->r[VR_DP0 + m->cmd] / duration * (1.0 - slip);
                double w = m->r[VR_DH0 + m->cmd] / duration * (1.0 - slip);
                double yaw = m->r[VR_YAW] + 0.5 * w * step;
                m->r[VR_X] += v * step * cos(yaw);
                m->r[VR_Y] += v * step * sin(yaw);
                m->r[VR_YAW] += w * step;
                m->cmd_time += step;
                moving = 1.0;
                for (int k = 0; k < 4; k++) {
                    m->r[VR_WHEEL0 + 5 * k + 0] = fabs(m->r[VR_RATE0 + m->cmd]);
                    m->r[VR_WHEEL0 + 5 * k + 1] = slip;
                }
                break;
            }
            m->cmd++;
            m->cmd_time = 0.0;
        }
        m->r[VR_COMMAND] = m->cmd < m->count ? (double)m->cmd : -1.0;
        m->r[VR_ENERGY] += moving * 0.004 * step;
        if (!moving) for (int k = 0; k < 4; k++) m->r[VR_WHEEL0 + 5 * k] = 0.0;
        m->time = now;
    }
    return fmi2OK;
}

fmi2Status fmi2CancelStep(fmi2Component c) { (void)c; return fmi2OK; }
fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *v) { (void)c; (void)s; *v = fmi2OK; return fmi2OK; }
fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *v) { (void)c; (void)s; *v = 0; return fmi2OK; }
fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *v) { (void)c; (void)s; *v = 0; return fmi2OK; }
fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *v) { (void)c; (void)s; *v = 0; return fmi2OK; }
fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *v) { (void)c; (void)s; *v = ""; return fmi2OK; }
const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }
fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean l, size_t n, const fmi2String s[]) { (void)c; (void)l; (void)n; (void)s; return fmi2OK; }
fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *s) { (void)c; (void)s; return fmi2Error; }
fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate s) { (void)c; (void)s; return fmi2Error; }
fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *s) { (void)c; (void)s; return fmi2Error; }
fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate s, size_t *n) { (void)c; (void)s; (void)n; return fmi2Error; }
fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate s, fmi2Byte b[], size_t n) { (void)c; (void)s; (void)b; (void)n; return fmi2Error; }
fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte b[], size_t n, fmi2FMUstate *s) { (void)c; (void)b; (void)n; (void)s; return fmi2Error; }
fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference u[], size_t nu, const fmi2ValueReference z[], size_t nz, const fmi2Real dv[], fmi2Real dz[]) { (void)c; (void)u; (void)nu; (void)z; (void)nz; (void)dv; (void)dz; return fmi2Error; }
fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer o[], const fmi2Real v[]) { (void)c; (void)vr; (void)n; (void)o; (void)v; return fmi2Error; }
fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer o[], fmi2Real v[]) { (void)c; (void)vr; (void)n; (void)o; (void)v; return fmi2Error; }
