/* Soak driver for the rover FMU: instantiate / reset / simulate cycles without fmpy, so the
 * model can run under valgrind or ASan. Built and run by tests/fmu/test_fmu_soak.py:
 *   cc -std=c99 -g -I<fmpy c-code> -I<sources> fmu_soak_driver.c <sources>/[a-z]*.c -lm
 *   valgrind --leak-check=full --error-exitcode=9 ./a.out CYCLES TERRAIN_FILE
 * Exit status 0 when every call succeeded and every pose stayed finite. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "fmi2Functions.h"
#include "variables.h"

static void logger(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status,
                   fmi2String category, fmi2String message, ...)
{
    (void)env;
    (void)name;
    (void)status;
    (void)category;
    fprintf(stderr, "fmu: %s\n", message);
}

int main(int argc, char **argv)
{
    long cycles = argc > 1 ? atol(argv[1]) : 100, cycle;
    const char *terrain = argc > 2 ? argv[2] : "";
    fmi2CallbackFunctions callbacks = {logger, calloc, free, NULL, NULL};
    fmi2Component c = NULL;
    for (cycle = 0; cycle < cycles; cycle++) {
        const fmi2ValueReference chain_count = VR_CHAIN_COUNT, file = VR_TERRAIN_FILE;
        fmi2ValueReference refs[6] = {VR_CHAIN_MAX_WHEEL_RATE, VR_CHAIN_DELTA_POSITION,
                                      VR_CHAIN_DELTA_HEADING, VR_CHAIN_MAX_WHEEL_RATE + 1,
                                      VR_CHAIN_DELTA_HEADING + 1, VR_SOIL_COHESION};
        fmi2Real values[6] = {0.05, 0.2, 0.3, 0.08, -0.6, 0.0};
        fmi2Integer count = 2;
        fmi2String path = (cycle % 3 == 2) ? "" : terrain;
        fmi2ValueReference out[3] = {VR_X, VR_Y, VR_YAW};
        fmi2Real pose[3];
        int k;
        values[5] = 50.0 + (double)(cycle % 7) * 100.0;
        if (cycle % 10 == 0) {
            if (c) fmi2FreeInstance(c);
            c = fmi2Instantiate("soak", fmi2CoSimulation, "", "", &callbacks, fmi2False,
                                fmi2False);
            if (!c) return 2;
        } else if (fmi2Reset(c) != fmi2OK) {
            return 3;
        }
        if (fmi2SetupExperiment(c, fmi2False, 0.0, 0.0, fmi2False, 0.0) != fmi2OK ||
            fmi2EnterInitializationMode(c) != fmi2OK ||
            fmi2SetReal(c, refs, 6, values) != fmi2OK ||
            fmi2SetInteger(c, &chain_count, 1, &count) != fmi2OK ||
            fmi2SetString(c, &file, 1, &path) != fmi2OK ||
            fmi2ExitInitializationMode(c) != fmi2OK)
            return 4;
        for (k = 0; k < 10; k++)
            if (fmi2DoStep(c, 0.5 * k, 0.5, fmi2True) != fmi2OK) return 5;
        if (fmi2GetReal(c, out, 3, pose) != fmi2OK) return 6;
        if (!isfinite(pose[0]) || !isfinite(pose[1]) || !isfinite(pose[2])) return 7;
    }
    if (c) {
        fmi2Terminate(c);
        fmi2FreeInstance(c);
    }
    printf("%ld cycles ok\n", cycles);
    return 0;
}
