/* Random FMI 2.0 call sequences against the native FMU compiled in (tests/test_native_fuzz.py builds this
 * file with the FMU's and the runtime's sources under -fsanitize=address,undefined).
 *
 *   fmi2_fuzz RESOURCE_URI GUID SEED CALLS INPUTS OUTPUTS
 *
 * INPUTS, OUTPUTS: comma-separated value references of Real inputs and outputs (most calls use them,
 * so that the sequences get past initialization into stepping, states and derivatives).
 * Every call is legal C (valid pointers, the array sizes it passes) but anything else goes: calls out of
 * state, unknown and mistyped value references, NaN, inf and huge values, rotations that are none,
 * negative and absurd steps, times that do not follow, states restored into other instances, damaged
 * serialized states, derivatives of anything. Statuses must be fmi2OK..fmi2Error (never Fatal or
 * Pending); a sanitizer report, a crash or a leak ends the process with a non-zero status. Prints the
 * number of calls per status. The sequences, slots, counts and the calls every version has are
 * tests/fuzz_driver.h's (shared with tests/fmi3_fuzz.c); the calls are FMI 2.0's. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"
#define FMI_(name) fmi2##name
#define FMI_STATE_(verb, tail) fmi2##verb##FMUstate##tail
#define FMI_DESERIALIZE fmi2DeSerializeFMUstate
#include "fuzz_driver.h"

/* the body FMU's derivatives of its last step (fmi2Functions.c, not an FMI function) */
fmi2Status ffrf2GetStepDerivative(fmi2Component, const fmi2ValueReference[], size_t, const fmi2ValueReference[], size_t,
                                  const fmi2Real[], fmi2Real[]);

static void logger(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status, fmi2String category,
                   fmi2String message, ...)
{
    (void)env;
    (void)name;
    (void)status;
    (void)category;
    (void)message;
}

#define MAX_VR 400

static int parse_list(const char *text, fmi2ValueReference *out, int max)
{
    int n = 0;
    while (text && *text && n < max) {
        out[n++] = (fmi2ValueReference)strtoul(text, (char **)&text, 10);
        if (*text == ',')
            text++;
    }
    return n;
}

/* the FMU under test: its Real inputs and outputs (main's arguments) */
static fmi2ValueReference inputs[MAX_VR], outputs[MAX_VR];
static int n_in, n_out;
static fmi2CallbackFunctions cb = {logger, calloc, free, NULL, NULL};

static void *instantiate(void) /* mostly right, sometimes a wrong GUID or location */
{
    const char *u = pick(10) ? fuzz_location : (pick(2) ? "file:///nonexistent" : "file://host/x");
    const char *g = pick(10) ? fuzz_token : "{bad}";
    return fmi2Instantiate("fuzz", fmi2CoSimulation, g, u, &cb, fmi2False, (fmi2Boolean)pick(2));
}

/* the calls of every version (tests/fuzz_driver.h shared_call): its doStep; the rest are the driver's */
static int do_step(void *c, double t, double H) { return (int)fmi2DoStep(c, t, H, fmi2True); }

static int call(fuzz_run *r, int i, int op, int sane)
{
    fmi2Component c = r->inst[i];
    fmi2Status s = fmi2OK;
    fmi2ValueReference vr[8];
    double x[8];
    int n = 1 + pick(8);
    for (int j = 0; j < n; j++) {
        vr[j] = sane ? inputs[pick(n_in)] : (fmi2ValueReference)(pick(20) ? pick(MAX_VR) : (int)next());
        x[j] = input_value(sane);
    }
    switch (op) {
    case 1: {
        fuzz_experiment e = experiment();
        s = fmi2SetupExperiment(c, fmi2False, 0.0, e.start, (fmi2Boolean)e.has_stop, e.stop);
        break;
    }
    case 2:
        s = fmi2EnterInitializationMode(c);
        break;
    case 3:
    case 4:
        s = fmi2SetReal(c, vr, (size_t)n, x);
        break;
    case 5: {
        fmi2Integer v[8];
        for (int j = 0; j < n; j++)
            v[j] = pick(3) ? pick(4) : (fmi2Integer)next();
        s = fmi2SetInteger(c, vr, (size_t)n, v);
        break;
    }
    case 6:
        s = fmi2GetReal(c, vr, (size_t)n, x);
        break;
    case 7: {
        fmi2Integer v[8];
        s = fmi2GetInteger(c, vr, (size_t)n, v);
        break;
    }
    case 8: {
        fmi2ValueReference u[8];
        double d[8];
        for (int j = 0; j < n; j++)
            u[j] = sane ? outputs[pick(n_out)] : (fmi2ValueReference)pick(MAX_VR);
        /* FMI's partial derivatives at the communication point, or the last step's (not FMI: docs/fmu.md) */
        s = pick(2) ? fmi2GetDirectionalDerivative(c, u, (size_t)n, vr, (size_t)n, x, d)
                    : ffrf2GetStepDerivative(c, u, (size_t)n, vr, (size_t)n, x, d);
        r->derivatives_ok += s == fmi2OK;
        break;
    }
    case 9: /* the whole start-up in one go, most of the time with the right calls */
        fmi2SetupExperiment(c, fmi2False, 0.0, 0.0, fmi2False, 0.0);
        fmi2EnterInitializationMode(c);
        s = fmi2ExitInitializationMode(c);
        r->t[i] = 0.0;
        break;
    default: {
        fmi2Real v;
        s = fmi2GetRealStatus(c, fmi2LastSuccessfulTime, &v);
    }
    }
    return (int)s;
}

FUZZ_MAIN(10, fmi2Error, 0)
