/* A minimal FMI 2.0 co-simulation host with no Python in it, on the FMI 2.0 headers
 * (ffrf_fmu/fmu/native/fmi2FunctionTypes.h; tests/test_native_host.py compiles it).
 *
 *   fmi2_host run  BINARY RESOURCE_URI GUID STEPS H INSTANCES CYCLES VR_IN VALUE VR_OUT...
 *       CYCLES times: instantiate INSTANCES instances, set VR_IN = VALUE in initialization mode,
 *       take STEPS doSteps of H, print "cycle instance value..." of VR_OUT (%.17g), free them all.
 *       Then dlclose and return 0: a crash at free, unload or exit shows in the exit status.
 *   fmi2_host derivative ...   as run, and after the steps also "d cycle instance value..." of
 *       ffrf2GetStepDerivative (the body FMU's derivatives of its last step, with fmi2GetDirectionalDerivative's
 *       arguments: docs/fmu.md) of VR_OUT with respect to VR_IN (seed 1).
 *   fmi2_host faults BINARY RESOURCE_URI GUID VR_REAL VR_INT VR_BAD_PARAM BAD_VALUE
 *       Each bad call twice on one instance, printing "call status" lines, then free and unload.
 */
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "host_loader.h" /* the same host for win64 (cross-compiled by zig, run in wine) */

#include "fmi2FunctionTypes.h" /* the standard's types (ffrf_fmu/fmu/native: compiled with -I there) */

typedef fmi2CallbackFunctions Callbacks;
typedef fmi2InstantiateTYPE *Instantiate;
typedef fmi2FreeInstanceTYPE *FreeInstance;
typedef fmi2SetupExperimentTYPE *Setup;
typedef fmi2EnterInitializationModeTYPE *Mode;
typedef fmi2SetRealTYPE *SetReal;
typedef fmi2GetRealTYPE *GetReal;
typedef fmi2SetIntegerTYPE *SetInteger;
typedef fmi2DoStepTYPE *DoStep;
typedef fmi2GetDirectionalDerivativeTYPE *Derivative; /* ffrf2GetStepDerivative has its arguments */

static void logger(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status, fmi2String category,
                   fmi2String fmt, ...)
{
    (void)env;
    va_list ap;
    va_start(ap, fmt);
    fprintf(stderr, "[%s] status %d %s: ", name, status, category ? category : "(null category)");
    vfprintf(stderr, fmt, ap);
    fprintf(stderr, "\n");
    va_end(ap);
}

int main(int argc, char **argv)
{
    if (argc < 5) return 2;
    void *lib = open_library(argv[2]);
    if (!lib) {
        fprintf(stderr, "dlopen: %s\n", library_error());
        return 4;
    }
    Instantiate instantiate = (Instantiate)sym(lib, "fmi2Instantiate");
    FreeInstance freeInstance = (FreeInstance)sym(lib, "fmi2FreeInstance");
    Setup setup = (Setup)sym(lib, "fmi2SetupExperiment");
    Mode enter = (Mode)sym(lib, "fmi2EnterInitializationMode");
    Mode leave = (Mode)sym(lib, "fmi2ExitInitializationMode");
    SetReal setReal = (SetReal)sym(lib, "fmi2SetReal");
    GetReal getReal = (GetReal)sym(lib, "fmi2GetReal");
    SetInteger setInteger = (SetInteger)sym(lib, "fmi2SetInteger");
    DoStep doStep = (DoStep)sym(lib, "fmi2DoStep");
    Callbacks cb = {logger, calloc, free, NULL, NULL};
    const char *uri = argv[3], *guid = argv[4];

    int derivative = strcmp(argv[1], "derivative") == 0;
    if (strcmp(argv[1], "run") == 0 || derivative) {
        Derivative getDerivative = derivative ? (Derivative)sym(lib, "ffrf2GetStepDerivative") : NULL;
        const double seed = 1.0;
        int steps = atoi(argv[5]), n = atoi(argv[7]), cycles = atoi(argv[8]);
        double H = atof(argv[6]);
        fmi2ValueReference vr_in = (fmi2ValueReference)atoi(argv[9]);
        double value = atof(argv[10]);
        int n_out = argc - 11;
        fmi2ValueReference *vr_out = calloc((size_t)n_out, sizeof *vr_out);
        double *out = calloc((size_t)n_out, sizeof *out);
        for (int i = 0; i < n_out; i++) vr_out[i] = (fmi2ValueReference)atoi(argv[11 + i]);
        fmi2Component c[8];
        for (int cycle = 0; cycle < cycles; cycle++) {
            for (int k = 0; k < n; k++) {
                char name[32];
                snprintf(name, sizeof name, "body%d", k);
                c[k] = instantiate(name, 1, guid, uri, &cb, 0, 0);
                if (!c[k]) return 5;
                if (setup(c[k], 0, 0.0, 0.0, 0, 0.0) || enter(c[k]) || setReal(c[k], &vr_in, 1, &value) || leave(c[k]))
                    return 6;
            }
            for (int s = 0; s < steps; s++)
                for (int k = 0; k < n; k++)
                    if (doStep(c[k], s * H, H, 1)) return 7;
            for (int k = 0; k < n; k++) {
                if (getReal(c[k], vr_out, (size_t)n_out, out)) return 8;
                printf("%d %d", cycle, k);
                for (int i = 0; i < n_out; i++) printf(" %.17g", out[i]);
                printf("\n");
                if (derivative) {
                    if (getDerivative(c[k], vr_out, (size_t)n_out, &vr_in, 1, &seed, out)) return 10;
                    printf("d %d %d", cycle, k);
                    for (int i = 0; i < n_out; i++) printf(" %.17g", out[i]);
                    printf("\n");
                }
            }
            for (int k = 0; k < n; k++) freeInstance(c[k]);
        }
        free(vr_out);
        free(out);
    } else if (strcmp(argv[1], "faults") == 0) {
        fmi2ValueReference vr_real = (fmi2ValueReference)atoi(argv[5]), vr_int = (fmi2ValueReference)atoi(argv[6]);
        fmi2ValueReference vr_bad = (fmi2ValueReference)atoi(argv[7]);
        double bad = atof(argv[8]), x = 0.0;
        fmi2ValueReference unknown = 1000000;
        int i1 = 1;
        fmi2Component c = instantiate("faulty", 1, guid, uri, &cb, 0, 0);
        if (!c) return 5;
        for (int rep = 0; rep < 2; rep++) {
            printf("getReal_unknown %d\n", getReal(c, &unknown, 1, &x));
            printf("setInteger_on_real %d\n", setInteger(c, &vr_real, 1, &i1));
            printf("getReal_on_integer %d\n", getReal(c, &vr_int, 1, &x));
            printf("doStep_before_init %d\n", doStep(c, 0.0, 0.01, 1));
        }
        setup(c, 0, 0.0, 0.0, 0, 0.0);
        enter(c);
        setReal(c, &vr_bad, 1, &bad);
        for (int rep = 0; rep < 2; rep++) printf("exitInit_bad_parameter %d\n", leave(c));
        for (int rep = 0; rep < 2; rep++) printf("doStep_after_failed_init %d\n", doStep(c, 0.0, 0.01, 1));
        freeInstance(c);
    }
    if (close_library(lib)) return 9;
    return 0;
}
