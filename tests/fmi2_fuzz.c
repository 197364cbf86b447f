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
 * number of calls per status. The sequences, slots and counts are tests/fuzz_driver.h's (shared with
 * tests/fmi3_fuzz.c); the calls are FMI 2.0's. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"
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

/* the FMU under test: its location, GUID, Real inputs and outputs (main's arguments) */
static const char *uri, *guid;
static fmi2ValueReference inputs[MAX_VR], outputs[MAX_VR];
static int n_in, n_out;
static fmi2CallbackFunctions cb = {logger, calloc, free, NULL, NULL};

static void *instantiate(void) /* mostly right, sometimes a wrong GUID or location */
{
    const char *u = pick(10) ? uri : (pick(2) ? "file:///nonexistent" : "file://host/x");
    const char *g = pick(10) ? guid : "{bad}";
    return fmi2Instantiate("fuzz", fmi2CoSimulation, g, u, &cb, fmi2False, (fmi2Boolean)pick(2));
}

static void free_instance(void *c)
{
    fmi2FreeInstance(c);
}

static void free_state(void *c, void **state)
{
    fmi2FreeFMUstate(c, state);
}

static int call(fuzz_run *r, int i, int op, int sane)
{
    fmi2Component c = r->inst[i];
    fmi2Status s = fmi2OK;
    fmi2ValueReference vr[8];
    double x[8];
    int n = 1 + pick(8);
    for (int j = 0; j < n; j++) {
        vr[j] = sane ? inputs[pick(n_in)] : (fmi2ValueReference)(pick(20) ? pick(MAX_VR) : (int)next());
        x[j] = sane && pick(10) ? 1e-3 * ((double)pick(2001) - 1000.0) : value();
    }
    switch (op) {
    case 1:
        s = fmi2SetupExperiment(c, fmi2False, 0.0, pick(4) ? 0.0 : value(), (fmi2Boolean)pick(2), value());
        break;
    case 2:
        s = fmi2EnterInitializationMode(c);
        break;
    case 3:
        s = fmi2ExitInitializationMode(c);
        r->t[i] = 0.0;
        break;
    case 4:
    case 5:
        s = fmi2SetReal(c, vr, (size_t)n, x);
        break;
    case 6: {
        fmi2Integer v[8];
        for (int j = 0; j < n; j++)
            v[j] = pick(3) ? pick(4) : (fmi2Integer)next();
        s = fmi2SetInteger(c, vr, (size_t)n, v);
        break;
    }
    case 7:
        s = fmi2GetReal(c, vr, (size_t)n, x);
        break;
    case 8: {
        fmi2Integer v[8];
        s = fmi2GetInteger(c, vr, (size_t)n, v);
        break;
    }
    case 9:
    case 10:
    case 11: { /* doStep: mostly where the FMU is, sometimes anywhere */
        double H = pick(8) ? 0.01 * (1 + pick(3)) : value();
        for (int j = 0; j < 20 && sane && pick(4); j++) { /* a few steps in a row */
            if (fmi2DoStep(c, r->t[i], H, fmi2True) != fmi2OK)
                break;
            r->t[i] += H;
            r->steps_ok++;
        }
        double tc = pick(8) ? r->t[i] : value();
        s = fmi2DoStep(c, tc, H, fmi2True);
        if (s == fmi2OK) {
            r->t[i] = tc + H;
            r->steps_ok++;
        }
        break;
    }
    case 12:
        s = fmi2GetFMUstate(c, &r->states[i]);
        break;
    case 13: { /* a state of any instance into this one (only its own FMU's states exist here) */
        int j = pick(N_INST);
        if (r->states[j])
            s = fmi2SetFMUstate(c, r->states[j]);
        r->restored_ok += s == fmi2OK && r->states[j];
        break;
    }
    case 14: { /* serialize, maybe damage, deserialize, set */
        if (!r->states[i])
            break;
        size_t size = 0;
        if (fmi2SerializedFMUstateSize(c, r->states[i], &size) != fmi2OK)
            break;
        free(r->blob);
        r->blob = malloc(size ? size : 1);
        if (!r->blob || fmi2SerializeFMUstate(c, r->states[i], (fmi2Byte *)r->blob, size) != fmi2OK)
            break;
        if (pick(2) && size)
            r->blob[pick((int)size)] ^= (unsigned char)(1 + pick(255));
        fmi2FMUstate other = NULL;
        size_t given = pick(5) ? size : (size_t)pick((int)size + 1);
        s = fmi2DeSerializeFMUstate(c, (const fmi2Byte *)r->blob, given, &other);
        if (s == fmi2OK) {
            s = fmi2SetFMUstate(c, other);
            fmi2FreeFMUstate(c, &other);
        }
        break;
    }
    case 15: {
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
    case 16: /* the whole start-up in one go, most of the time with the right calls */
        fmi2SetupExperiment(c, fmi2False, 0.0, 0.0, fmi2False, 0.0);
        fmi2EnterInitializationMode(c);
        s = fmi2ExitInitializationMode(c);
        r->t[i] = 0.0;
        break;
    default:
        switch (pick(4)) {
        case 0:
            s = fmi2Reset(c);
            r->t[i] = 0.0;
            break;
        case 1:
            s = fmi2Terminate(c);
            break;
        case 2: {
            fmi2Real v;
            s = fmi2GetRealStatus(c, fmi2LastSuccessfulTime, &v);
            break;
        }
        default:
            s = fmi2SetDebugLogging(c, (fmi2Boolean)pick(2), 0, NULL);
        }
    }
    return (int)s;
}

int main(int argc, char **argv)
{
    if (argc < 7)
        return 2;
    n_in = parse_list(argv[5], inputs, MAX_VR);
    n_out = parse_list(argv[6], outputs, MAX_VR);
    if (!n_in || !n_out)
        return 2;
    uri = argv[1];
    guid = argv[2];
    const fuzz_api api = {18, fmi2Error, 0, instantiate, free_instance, free_state, call};
    return fuzz_main(&api, strtoull(argv[3], NULL, 10), atol(argv[4]));
}
