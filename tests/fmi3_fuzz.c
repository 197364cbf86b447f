/* Random FMI 3.0 call sequences against the native FMU's FMI 3.0 layer compiled in (tests/test_fmi3.py builds
 * this file with fmi3Functions.c, the model and the runtime under -fsanitize=address,undefined): the FMI 3.0
 * twin of tests/fmi2_fuzz.c.
 *
 *   fmi3_fuzz RESOURCE_PATH TOKEN SEED CALLS INPUTS OUTPUTS
 *
 * INPUTS, OUTPUTS: comma-separated VR:N of the Float64 input and output arrays (N elements each; most calls
 * use them, so that the sequences get past initialization into stepping, states and derivatives).
 * Every call is legal C (valid pointers, arrays of the sizes it passes) but anything else goes: calls out of
 * state, unknown and mistyped references, nValues that do not match, NaN, inf and huge values, rotations that
 * are none, absurd steps and times, states restored into other instances, damaged serialized states,
 * derivatives and adjoints of anything, calls of the functions this FMU does not provide. Statuses must be
 * fmi3OK..fmi3Error (never Fatal); a sanitizer report, a crash or a leak ends the process with a non-zero
 * status. Prints the number of calls per status and how far the sequences got. The sequences, slots, counts and
 * the calls every version has are tests/fuzz_driver.h's (shared with tests/fmi2_fuzz.c); the calls are FMI 3.0's. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "fmi3_types.h"
#include "fmi3Functions.h"
#define FMI_(name) fmi3##name
#define FMI_STATE_(verb, tail) fmi3##verb##FMUState##tail
#define FMI_DESERIALIZE fmi3DeserializeFMUState
#include "fuzz_driver.h"

/* the body FMU's derivatives of its last step (fmi3Functions.c, not FMI functions) */
fmi3Status ffrf3GetStepDirectionalDerivative(fmi3Instance, const fmi3ValueReference[], size_t, const fmi3ValueReference[],
                                             size_t, const fmi3Float64[], size_t, fmi3Float64[], size_t);
fmi3Status ffrf3GetStepAdjointDerivative(fmi3Instance, const fmi3ValueReference[], size_t, const fmi3ValueReference[],
                                         size_t, const fmi3Float64[], size_t, fmi3Float64[], size_t);

static void log_message(fmi3InstanceEnvironment env, fmi3Status status, fmi3String category, fmi3String message)
{
    (void)env;
    (void)status;
    (void)category;
    (void)message;
}

#define MAX_VR 200
#define MAX_VALUES 64

typedef struct {
    fmi3ValueReference vr;
    int n;
} array_ref;

static int parse_list(const char *text, array_ref *out, int max)
{
    int n = 0;
    while (text && *text && n < max) {
        out[n].vr = (fmi3ValueReference)strtoul(text, (char **)&text, 10);
        out[n].n = *text == ':' ? (int)strtol(text + 1, (char **)&text, 10) : 1;
        n++;
        if (*text == ',')
            text++;
    }
    return n;
}

/* up to 4 references and their values: mostly the given arrays with the right count, sometimes anything */
static size_t refs(int sane, const array_ref *list, int n_list, fmi3ValueReference *vr, size_t *n_vr)
{
    size_t total = 0;
    *n_vr = (size_t)(1 + pick(4));
    for (size_t j = 0; j < *n_vr; j++) {
        const array_ref *a = &list[pick(n_list)];
        vr[j] = sane ? a->vr : (fmi3ValueReference)(pick(20) ? pick(MAX_VR) : (int)next());
        total += sane ? (size_t)a->n : (size_t)pick(10);
    }
    if (!sane && pick(2))
        total = (size_t)pick(MAX_VALUES);
    return total < MAX_VALUES ? total : MAX_VALUES;
}

/* the FMU under test: its Float64 input and output arrays (main's arguments) */
static array_ref inputs[MAX_VR], outputs[MAX_VR];
static int n_in, n_out;

static void *instantiate(void) /* mostly right, sometimes a wrong token, path or event mode */
{
    const char *p = pick(10) ? fuzz_location : (pick(2) ? "/nonexistent/" : "file://host/x");
    const char *g = pick(10) ? fuzz_token : "{bad}";
    return fmi3InstantiateCoSimulation("fuzz", g, p, fmi3False, (fmi3Boolean)pick(2), pick(20) == 0, (fmi3Boolean)pick(2),
                                       NULL, 0, NULL, log_message, NULL);
}

/* the calls of every version (tests/fuzz_driver.h shared_call): its doStep; the rest are the driver's */
static int do_step(void *c, double t, double H)
{
    fmi3Boolean event, stop, early;
    fmi3Float64 last;
    return (int)fmi3DoStep(c, t, H, fmi3True, &event, &stop, &early, &last);
}

static int call(fuzz_run *r, int i, int op, int sane)
{
    fmi3Instance c = r->inst[i];
    fmi3Status s = fmi3OK;
    fmi3ValueReference vr[4], u[4];
    size_t n_vr, n_u;
    double x[MAX_VALUES], y[MAX_VALUES];
    size_t nx = refs(sane, inputs, n_in, vr, &n_vr);
    for (size_t j = 0; j < MAX_VALUES; j++)
        x[j] = input_value(sane);
    switch (op) {
    case 1: {
        fuzz_experiment e = experiment();
        s = fmi3EnterInitializationMode(c, fmi3False, 0.0, e.start, (fmi3Boolean)e.has_stop, e.stop);
        break;
    }
    case 2:
    case 3:
        s = fmi3SetFloat64(c, vr, n_vr, x, nx);
        break;
    case 4: {
        fmi3Int32 v[MAX_VALUES];
        for (size_t j = 0; j < MAX_VALUES; j++)
            v[j] = pick(3) ? pick(4) : (fmi3Int32)next();
        s = fmi3SetInt32(c, vr, n_vr, v, nx);
        break;
    }
    case 5: {
        size_t ny = refs(sane, outputs, n_out, u, &n_u);
        s = fmi3GetFloat64(c, u, n_u, y, ny);
        break;
    }
    case 6: {
        fmi3Int32 v[MAX_VALUES];
        s = fmi3GetInt32(c, vr, n_vr, v, nx);
        break;
    }
    case 7:
    case 8: { /* directional or adjoint derivative of anything */
        size_t ny = refs(sane, outputs, n_out, u, &n_u);
        int step = pick(2); /* FMI's partial derivatives at the communication point, or the last step's (docs/fmu.md) */
        if (op == 7) {
            s = step ? ffrf3GetStepDirectionalDerivative(c, u, n_u, vr, n_vr, x, nx, y, ny)
                     : fmi3GetDirectionalDerivative(c, u, n_u, vr, n_vr, x, nx, y, ny);
            r->derivatives_ok += s == fmi3OK;
        } else {
            s = step ? ffrf3GetStepAdjointDerivative(c, u, n_u, vr, n_vr, x, ny, y, nx)
                     : fmi3GetAdjointDerivative(c, u, n_u, vr, n_vr, x, ny, y, nx);
            r->adjoints_ok += s == fmi3OK;
        }
        break;
    }
    case 9: /* the whole start-up in one go */
        fmi3EnterInitializationMode(c, fmi3False, 0.0, 0.0, fmi3False, 0.0);
        s = fmi3ExitInitializationMode(c);
        r->t[i] = 0.0;
        break;
    default: { /* what this FMU does not provide */
        fmi3Boolean b[MAX_VALUES];
        fmi3Int32 orders[MAX_VALUES] = {0};
        size_t nd = 0;
        switch (pick(5)) {
        case 0:
            s = fmi3GetBoolean(c, vr, n_vr, b, nx);
            break;
        case 1:
            s = fmi3EnterEventMode(c);
            break;
        case 2:
            s = fmi3GetNumberOfVariableDependencies(c, vr[0], &nd);
            break;
        case 3:
            s = fmi3EnterStepMode(c);
            break;
        default:
            s = fmi3GetOutputDerivatives(c, vr, n_vr, orders, x, nx);
        }
        break;
    }
    }
    return (int)s;
}

FUZZ_MAIN(10, fmi3Error, 1)
