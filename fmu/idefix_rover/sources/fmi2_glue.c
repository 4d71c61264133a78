/* FMI 2.0 co-simulation interface of the rover. State lives in the Instance only. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"
#include "idefix.h"

static const double REAL_START[N_REAL] = REAL_DEFAULTS;

static void log_message(Instance *inst, fmi2Status status, const char *category,
                        const char *message)
{
    /* The message is the format itself ('%' doubled): an importer's logger that does not
     * expand variadic arguments (e.g. a Python callback) still receives the text. */
    fmi2CallbackLogger logger = (fmi2CallbackLogger)inst->logger;
    char format[2048];
    size_t n = 0;
    for (; *message && n + 2 < sizeof(format); message++) {
        if (*message == '%') format[n++] = '%';
        format[n++] = *message;
    }
    format[n] = '\0';
    if (logger) logger((fmi2ComponentEnvironment)inst->env, inst->instance_name, status, category,
                       format);
}

static char *copy_string(const char *text)
{
    char *copy = (char *)malloc(strlen(text ? text : "") + 1);
    if (copy) strcpy(copy, text ? text : "");
    return copy;
}

static void set_defaults(Instance *inst)
{
    memcpy(inst->r, REAL_START, sizeof(REAL_START));
    inst->chain_count = 0;
    free(inst->terrain_file);
    inst->terrain_file = copy_string("");
    inst->time = 0.0;
    inst->initialised = 0;
}

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t n,
                               const fmi2String categories[])
{
    (void)n;
    (void)categories;
    ((Instance *)c)->logging = loggingOn;
    return fmi2OK;
}

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String resourceLocation, const fmi2CallbackFunctions *functions,
                              fmi2Boolean visible, fmi2Boolean loggingOn)
{
    Instance *inst;
    (void)fmuGUID;
    (void)resourceLocation;
    (void)visible;
    if (fmuType != fmi2CoSimulation) return NULL;
    inst = (Instance *)calloc(1, sizeof(Instance));
    if (!inst) return NULL;
    inst->instance_name = copy_string(instanceName);
    inst->logger = functions ? (void (*)(void))functions->logger : NULL;
    inst->env = functions ? functions->componentEnvironment : NULL;
    inst->logging = loggingOn;
    set_defaults(inst);
    return inst;
}

void fmi2FreeInstance(fmi2Component c)
{
    Instance *inst = (Instance *)c;
    if (!inst) return;
    terrain_free(&inst->terrain);
    soil_grid_free(&inst->grid);
    free(inst->terrain_file);
    free(inst->instance_name);
    free(inst);
}

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                               fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime)
{
    (void)toleranceDefined;
    (void)tolerance;
    (void)stopTimeDefined;
    (void)stopTime;
    ((Instance *)c)->time = startTime;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c)
{
    (void)c;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c)
{
    Instance *inst = (Instance *)c;
    char message[1024];
    if (rover_initialise(inst, message, sizeof(message)) != 0) {
        log_message(inst, fmi2Error, "logStatusError", message);
        return fmi2Error;
    }
    inst->initialised = 1;
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component c)
{
    (void)c;
    return fmi2OK;
}

/* Back to the state after instantiation. Terrain data and the grid allocation stay cached:
 * they are reloaded only when the file or the extent changes. */
fmi2Status fmi2Reset(fmi2Component c)
{
    set_defaults((Instance *)c);
    return fmi2OK;
}

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                       fmi2Real value[])
{
    Instance *inst = (Instance *)c;
    size_t k;
    for (k = 0; k < nvr; k++) {
        if (vr[k] >= N_REAL) return fmi2Error;
        value[k] = inst->r[vr[k]];
    }
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                       const fmi2Real value[])
{
    Instance *inst = (Instance *)c;
    size_t k;
    for (k = 0; k < nvr; k++) {
        if (vr[k] >= FIRST_OUTPUT_VR) {
            log_message(inst, fmi2Error, "logStatusError", "cannot set an output");
            return fmi2Error;
        }
        inst->r[vr[k]] = value[k];
    }
    return fmi2OK;
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          fmi2Integer value[])
{
    size_t k;
    for (k = 0; k < nvr; k++) {
        if (vr[k] != VR_CHAIN_COUNT) return fmi2Error;
        value[k] = ((Instance *)c)->chain_count;
    }
    return fmi2OK;
}

fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          const fmi2Integer value[])
{
    Instance *inst = (Instance *)c;
    size_t k;
    for (k = 0; k < nvr; k++) {
        if (vr[k] != VR_CHAIN_COUNT || value[k] < 0 || value[k] > MAX_COMMANDS) {
            log_message(inst, fmi2Error, "logStatusError", "chain.count must be 0..MAX_COMMANDS");
            return fmi2Error;
        }
        inst->chain_count = value[k];
    }
    return fmi2OK;
}

fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          fmi2Boolean value[])
{
    (void)c;
    (void)vr;
    (void)value;
    return nvr == 0 ? fmi2OK : fmi2Error;
}

fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          const fmi2Boolean value[])
{
    (void)c;
    (void)vr;
    (void)value;
    return nvr == 0 ? fmi2OK : fmi2Error;
}

fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                         fmi2String value[])
{
    size_t k;
    for (k = 0; k < nvr; k++) {
        if (vr[k] != VR_TERRAIN_FILE) return fmi2Error;
        value[k] = ((Instance *)c)->terrain_file;
    }
    return fmi2OK;
}

fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                         const fmi2String value[])
{
    Instance *inst = (Instance *)c;
    size_t k;
    for (k = 0; k < nvr; k++) {
        if (vr[k] != VR_TERRAIN_FILE) return fmi2Error;
        free(inst->terrain_file);
        inst->terrain_file = copy_string(value[k]);
    }
    return fmi2OK;
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint,
                      fmi2Real communicationStepSize, fmi2Boolean noSetFMUStatePriorToCurrentPoint)
{
    Instance *inst = (Instance *)c;
    double largest = inst->r[VR_SOLVER_STEP], dt;
    long n, k;
    (void)noSetFMUStatePriorToCurrentPoint;
    if (!inst->initialised || !(communicationStepSize >= 0.0)) return fmi2Error;
    inst->time = currentCommunicationPoint;
    if (communicationStepSize == 0.0) return fmi2OK;
    /* equal internal steps no longer than solver.step */
    n = (long)ceil(communicationStepSize / largest - 1e-9);
    if (n < 1) n = 1;
    dt = communicationStepSize / (double)n;
    for (k = 0; k < n; k++) rover_step(inst, dt);
    inst->time = currentCommunicationPoint + communicationStepSize;
    rover_write_outputs(inst);
    if (!isfinite(inst->x) || !isfinite(inst->y) || !isfinite(inst->z) || !isfinite(inst->yaw)) {
        log_message(inst, fmi2Error, "logStatusError", "pose is not finite");
        return fmi2Error;
    }
    return fmi2OK;
}

fmi2Status fmi2CancelStep(fmi2Component c)
{
    (void)c;
    return fmi2Error;
}

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *s)
{
    (void)c;
    (void)s;
    return fmi2Error;
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate s)
{
    (void)c;
    (void)s;
    return fmi2Error;
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *s)
{
    (void)c;
    (void)s;
    return fmi2Error;
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate s, size_t *size)
{
    (void)c;
    (void)s;
    (void)size;
    return fmi2Error;
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate s, fmi2Byte bytes[], size_t size)
{
    (void)c;
    (void)s;
    (void)bytes;
    (void)size;
    return fmi2Error;
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte bytes[], size_t size,
                                   fmi2FMUstate *s)
{
    (void)c;
    (void)bytes;
    (void)size;
    (void)s;
    return fmi2Error;
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference u[], size_t nu,
                                        const fmi2ValueReference z[], size_t nz,
                                        const fmi2Real du[], fmi2Real dz[])
{
    (void)c;
    (void)u;
    (void)nu;
    (void)z;
    (void)nz;
    (void)du;
    (void)dz;
    return fmi2Error;
}

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                       const fmi2Integer order[], const fmi2Real value[])
{
    (void)c;
    (void)vr;
    (void)nvr;
    (void)order;
    (void)value;
    return fmi2Error;
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[],
                                        size_t nvr, const fmi2Integer order[], fmi2Real value[])
{
    (void)c;
    (void)vr;
    (void)nvr;
    (void)order;
    (void)value;
    return fmi2Error;
}

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value)
{
    (void)c;
    (void)s;
    *value = fmi2OK;
    return fmi2OK;
}

fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value)
{
    if (s != fmi2LastSuccessfulTime) return fmi2Discard;
    *value = ((Instance *)c)->time;
    return fmi2OK;
}

fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value)
{
    (void)c;
    (void)s;
    (void)value;
    return fmi2Discard;
}

fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value)
{
    (void)c;
    (void)s;
    (void)value;
    return fmi2Discard;
}

fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value)
{
    (void)c;
    (void)s;
    (void)value;
    return fmi2Discard;
}
