/* A minimal FMI 3.0 co-simulation host with no Python in it, written against the FMI 3.0 headers
 * (ffrf_fmu/fmu/native/fmi3_types.h; tests/test_fmi3.py compiles it).
 *
 *   fmi3_host BINARY RESOURCE_PATH TOKEN STEPS H VR_IN N_IN VALUE... -- VR_OUT:N ...
 *       instantiate, set the Float64 array VR_IN (N_IN values) in initialization mode, take STEPS
 *       doSteps of H from 0, print every element of each VR_OUT (N values) with %.17g on one line,
 *       then fmi3GetFMUState / two more doSteps / fmi3SetFMUState / the same two doSteps again and
 *       print "replay 1" when the outputs repeat bit for bit, fmi3Reset and "reset 0" when the outputs
 *       are readable again in initialization mode, then bad calls (an unknown reference, a wrong count, a
 *       set of an output, doStep in initialization mode, a damaged serialized state, a NULL state), each
 *       twice, and "faults K" with K the number that returned fmi3Error; free and unload. Any failed
 *       call of the good path: exit status 1.
 *   BINARY "-" takes the fmi3 functions from the host itself (linked in, -rdynamic: the sanitizer build).
 */
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "host_loader.h"

#include "fmi3_types.h"

static void log_message(fmi3InstanceEnvironment env, fmi3Status status, fmi3String category, fmi3String message)
{
    (void)env;
    fprintf(stderr, "[%d %s] %s\n", (int)status, category, message);
}

/* a function of the FMU's binary by its name and type (host_loader.h sym: missing, exit status 3 naming it) */
#define LOAD(T, name) T *name = (T *)sym(lib, #name);
#define CHECK(call) do { fmi3Status s_ = (call); if (s_ != fmi3OK) { fprintf(stderr, "%s: status %d\n", #call, (int)s_); return 1; } } while (0)

int main(int argc, char **argv)
{
    if (argc < 9) {
        fprintf(stderr, "usage: fmi3_host BINARY RESOURCE_PATH TOKEN STEPS H VR_IN N_IN VALUE... -- VR_OUT:N ...\n");
        return 2;
    }
    void *lib = open_library(argv[1]);
    if (!lib) {
        fprintf(stderr, "cannot load %s: %s\n", argv[1], library_error());
        return 1;
    }
    LOAD(fmi3InstantiateCoSimulationTYPE, fmi3InstantiateCoSimulation)
    LOAD(fmi3EnterInitializationModeTYPE, fmi3EnterInitializationMode)
    LOAD(fmi3ExitInitializationModeTYPE, fmi3ExitInitializationMode)
    LOAD(fmi3SetFloat64TYPE, fmi3SetFloat64)
    LOAD(fmi3GetFloat64TYPE, fmi3GetFloat64)
    LOAD(fmi3DoStepTYPE, fmi3DoStep)
    LOAD(fmi3GetFMUStateTYPE, fmi3GetFMUState)
    LOAD(fmi3SetFMUStateTYPE, fmi3SetFMUState)
    LOAD(fmi3FreeFMUStateTYPE, fmi3FreeFMUState)
    LOAD(fmi3ResetTYPE, fmi3Reset)
    LOAD(fmi3TerminateTYPE, fmi3Terminate)
    LOAD(fmi3FreeInstanceTYPE, fmi3FreeInstance)
    LOAD(fmi3SerializedFMUStateSizeTYPE, fmi3SerializedFMUStateSize)
    LOAD(fmi3SerializeFMUStateTYPE, fmi3SerializeFMUState)
    LOAD(fmi3DeserializeFMUStateTYPE, fmi3DeserializeFMUState)
    int steps = atoi(argv[4]);
    double H = atof(argv[5]);
    fmi3ValueReference vr_in = (fmi3ValueReference)strtoul(argv[6], NULL, 10);
    int n_in = atoi(argv[7]), a = 8;
    double in[16];
    for (int i = 0; i < n_in && i < 16; i++)
        in[i] = atof(argv[a++]);
    if (a >= argc || strcmp(argv[a++], "--") != 0)
        return 2;
    fmi3ValueReference out_vr[64];
    size_t n_out = 0, n_values = 0;
    for (; a < argc && n_out < 64; a++) {
        char *colon = strchr(argv[a], ':');
        out_vr[n_out++] = (fmi3ValueReference)strtoul(argv[a], NULL, 10);
        n_values += colon ? (size_t)atoi(colon + 1) : 1;
    }
    double *out = malloc(sizeof(double) * n_values), *again = malloc(sizeof(double) * n_values);
    if (!out || !again)
        return 1;
    fmi3Instance c = fmi3InstantiateCoSimulation("host", argv[3], argv[2], fmi3False, fmi3False, fmi3False, fmi3False,
                                                 NULL, 0, NULL, log_message, NULL);
    if (!c)
        return 1;
    fmi3Boolean event, terminate, early;
    fmi3Float64 last;
    CHECK(fmi3EnterInitializationMode(c, fmi3False, 0.0, 0.0, fmi3False, 0.0));
    CHECK(fmi3SetFloat64(c, &vr_in, 1, in, (size_t)n_in));
    CHECK(fmi3ExitInitializationMode(c));
    for (int k = 0; k < steps; k++)
        CHECK(fmi3DoStep(c, k * H, H, fmi3True, &event, &terminate, &early, &last));
    CHECK(fmi3GetFloat64(c, out_vr, n_out, out, n_values));
    for (size_t i = 0; i < n_values; i++)
        printf("%s%.17g", i ? " " : "", out[i]);
    printf("\n");
    fmi3FMUState state = NULL;
    CHECK(fmi3GetFMUState(c, &state));
    for (int k = steps; k < steps + 2; k++)
        CHECK(fmi3DoStep(c, k * H, H, fmi3False, &event, &terminate, &early, &last));
    CHECK(fmi3GetFloat64(c, out_vr, n_out, out, n_values));
    const fmi3Float64 first_last = last;
    CHECK(fmi3SetFMUState(c, state));
    for (int k = steps; k < steps + 2; k++)
        CHECK(fmi3DoStep(c, k * H, H, fmi3False, &event, &terminate, &early, &last));
    CHECK(fmi3GetFloat64(c, out_vr, n_out, again, n_values));
    printf("replay %d\n", memcmp(out, again, sizeof(double) * n_values) == 0 && last == first_last);
    size_t size = 0;
    CHECK(fmi3SerializedFMUStateSize(c, state, &size));
    unsigned char *bytes = malloc(size);
    if (!bytes)
        return 1;
    CHECK(fmi3SerializeFMUState(c, state, bytes, size));
    CHECK(fmi3FreeFMUState(c, &state));
    CHECK(fmi3Terminate(c));
    CHECK(fmi3Reset(c));
    CHECK(fmi3EnterInitializationMode(c, fmi3False, 0.0, 0.0, fmi3False, 0.0));
    printf("reset %d\n", (int)fmi3GetFloat64(c, out_vr, n_out, out, n_values));
    int faults = 0;
    fmi3ValueReference unknown = 1000000;
    bytes[size / 2] ^= 1; /* the checksum no longer holds */
    for (int twice = 0; twice < 2; twice++) {
        fmi3FMUState damaged = NULL;
        faults += fmi3GetFloat64(c, &unknown, 1, out, 1) == fmi3Error;
        faults += fmi3GetFloat64(c, out_vr, 1, out, n_values + 1) == fmi3Error;
        faults += fmi3SetFloat64(c, out_vr, 1, out, n_values) == fmi3Error; /* outputs cannot be set */
        faults += fmi3DoStep(c, 0.0, H, fmi3True, &event, &terminate, &early, &last) == fmi3Error;
        faults += fmi3DeserializeFMUState(c, bytes, size, &damaged) == fmi3Error && damaged == NULL;
        faults += fmi3SetFMUState(c, NULL) == fmi3Error;
    }
    printf("faults %d\n", faults);
    free(bytes);
    fmi3FreeInstance(c);
    close_library(lib);
    free(out);
    free(again);
    return 0;
}
