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
 * number of calls per status. */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"

/* the body FMU's derivatives of its last step (fmi2Functions.c, not an FMI function) */
fmi2Status ffrf2GetStepDerivative(fmi2Component, const fmi2ValueReference[], size_t, const fmi2ValueReference[], size_t,
                                  const fmi2Real[], fmi2Real[]);

static uint64_t rng = 88172645463325252ull;

static uint64_t next(void)
{
    rng ^= rng << 13;
    rng ^= rng >> 7;
    rng ^= rng << 17;
    return rng;
}

static int pick(int n)
{
    return (int)(next() % (uint64_t)n);
}

static double value(void)
{
    static const double special[] = {0.0, 1.0, -1.0, 0.5, 2.0, 1e308, -1e308, 1e-300, 7.0, 0.01};
    switch (pick(6)) {
    case 0:
        return NAN;
    case 1:
        return pick(2) ? INFINITY : -INFINITY;
    case 2:
        return special[pick(10)];
    default:
        return ((double)(next() % 2000001) - 1000000.0) * 1e-6 * (pick(4) ? 1.0 : 100.0);
    }
}

static void logger(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status, fmi2String category,
                   fmi2String message, ...)
{
    (void)env;
    (void)name;
    (void)status;
    (void)category;
    (void)message;
}

#define N_INST 3
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

int main(int argc, char **argv)
{
    if (argc < 7)
        return 2;
    static fmi2ValueReference inputs[MAX_VR], outputs[MAX_VR];
    int n_in = parse_list(argv[5], inputs, MAX_VR), n_out = parse_list(argv[6], outputs, MAX_VR);
    if (!n_in || !n_out)
        return 2;
    const char *uri = argv[1], *guid = argv[2];
    rng ^= strtoull(argv[3], NULL, 10) * 0x9E3779B97F4A7C15ull;
    long calls = atol(argv[4]);
    fmi2CallbackFunctions cb = {logger, calloc, free, NULL, NULL};
    fmi2Component inst[N_INST] = {NULL};
    fmi2FMUstate states[N_INST] = {NULL};
    double t[N_INST] = {0};
    long count[6] = {0}, steps_ok = 0, restored_ok = 0, derivatives_ok = 0;
    unsigned char *blob = NULL;
    size_t blob_size = 0;
    for (long k = 0; k < calls; k++) {
        int i = pick(N_INST);
        fmi2Component c = inst[i];
        fmi2Status s = fmi2OK;
        fmi2ValueReference vr[8];
        double x[8];
        int n = 1 + pick(8);
        int sane = pick(4) != 0; /* mostly inputs with moderate values: the runs get somewhere */
        for (int j = 0; j < n; j++) {
            vr[j] = sane ? inputs[pick(n_in)] : (fmi2ValueReference)(pick(20) ? pick(MAX_VR) : (int)next());
            x[j] = sane && pick(10) ? 1e-3 * ((double)pick(2001) - 1000.0) : value();
        }
        int op = c ? pick(18) : 0;
        switch (op) {
        case 0: { /* (re)instantiate: mostly right, sometimes a wrong GUID or location */
            if (c)
                fmi2FreeInstance(c);
            if (states[i]) {
                free(states[i]); /* fmi2FreeFMUstate needs an instance: the state is a malloc'd block */
                states[i] = NULL;
            }
            const char *u = pick(10) ? uri : (pick(2) ? "file:///nonexistent" : "file://host/x");
            const char *g = pick(10) ? guid : "{bad}";
            inst[i] = fmi2Instantiate("fuzz", fmi2CoSimulation, g, u, &cb, fmi2False, (fmi2Boolean)pick(2));
            t[i] = 0.0;
            continue;
        }
        case 1:
            s = fmi2SetupExperiment(c, fmi2False, 0.0, pick(4) ? 0.0 : value(), (fmi2Boolean)pick(2), value());
            break;
        case 2:
            s = fmi2EnterInitializationMode(c);
            break;
        case 3:
            s = fmi2ExitInitializationMode(c);
            t[i] = 0.0;
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
                if (fmi2DoStep(c, t[i], H, fmi2True) != fmi2OK)
                    break;
                t[i] += H;
                steps_ok++;
            }
            double tc = pick(8) ? t[i] : value();
            s = fmi2DoStep(c, tc, H, fmi2True);
            if (s == fmi2OK) {
                t[i] = tc + H;
                steps_ok++;
            }
            break;
        }
        case 12:
            s = fmi2GetFMUstate(c, &states[i]);
            break;
        case 13: { /* a state of any instance into this one (only its own FMU's states exist here) */
            int j = pick(N_INST);
            if (states[j])
                s = fmi2SetFMUstate(c, states[j]);
            restored_ok += s == fmi2OK && states[j];
            break;
        }
        case 14: { /* serialize, maybe damage, deserialize, set */
            if (!states[i])
                break;
            size_t size = 0;
            if (fmi2SerializedFMUstateSize(c, states[i], &size) != fmi2OK)
                break;
            free(blob);
            blob = malloc(size ? size : 1);
            blob_size = size;
            if (!blob || fmi2SerializeFMUstate(c, states[i], (fmi2Byte *)blob, size) != fmi2OK)
                break;
            if (pick(2) && blob_size)
                blob[pick((int)blob_size)] ^= (unsigned char)(1 + pick(255));
            fmi2FMUstate other = NULL;
            size_t given = pick(5) ? blob_size : (size_t)pick((int)blob_size + 1);
            s = fmi2DeSerializeFMUstate(c, (const fmi2Byte *)blob, given, &other);
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
            derivatives_ok += s == fmi2OK;
            break;
        }
        case 16: /* the whole start-up in one go, most of the time with the right calls */
            fmi2SetupExperiment(c, fmi2False, 0.0, 0.0, fmi2False, 0.0);
            fmi2EnterInitializationMode(c);
            s = fmi2ExitInitializationMode(c);
            t[i] = 0.0;
            break;
        default:
            switch (pick(4)) {
            case 0:
                s = fmi2Reset(c);
                t[i] = 0.0;
                break;
            case 1:
                s = fmi2Terminate(c);
                break;
            case 2: {
                fmi2Real r;
                s = fmi2GetRealStatus(c, fmi2LastSuccessfulTime, &r);
                break;
            }
            default:
                s = fmi2SetDebugLogging(c, (fmi2Boolean)pick(2), 0, NULL);
            }
        }
        if (s < fmi2OK || s > fmi2Error) {
            fprintf(stderr, "call %ld (op %d): status %d\n", k, op, (int)s);
            return 3;
        }
        count[s]++;
    }
    for (int i = 0; i < N_INST; i++) {
        if (inst[i] && states[i])
            fmi2FreeFMUstate(inst[i], &states[i]);
        free(states[i]);
        if (inst[i])
            fmi2FreeInstance(inst[i]);
    }
    free(blob);
    printf("ok %ld discard %ld error %ld steps_ok %ld restored_ok %ld derivatives_ok %ld\n", count[0], count[2],
           count[3], steps_ok, restored_ok, derivatives_ok);
    return 0;
}
