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
 * status. Prints the number of calls per status and how far the sequences got. The sequences, slots and counts
 * are tests/fuzz_driver.h's (shared with tests/fmi2_fuzz.c); the calls are FMI 3.0's. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "fmi3_types.h"
#include "fmi3Functions.h"
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

/* the FMU under test: its resource path, instantiation token, Float64 input and output arrays (main's arguments) */
static const char *path, *token;
static array_ref inputs[MAX_VR], outputs[MAX_VR];
static int n_in, n_out;

static void *instantiate(void) /* mostly right, sometimes a wrong token, path or event mode */
{
    const char *p = pick(10) ? path : (pick(2) ? "/nonexistent/" : "file://host/x");
    const char *g = pick(10) ? token : "{bad}";
    return fmi3InstantiateCoSimulation("fuzz", g, p, fmi3False, (fmi3Boolean)pick(2), pick(20) == 0, (fmi3Boolean)pick(2),
                                       NULL, 0, NULL, log_message, NULL);
}

static void free_instance(void *c)
{
    fmi3FreeInstance(c);
}

static void free_state(void *c, void **state)
{
    fmi3FreeFMUState(c, state);
}

static int call(fuzz_run *r, int i, int op, int sane)
{
    fmi3Instance c = r->inst[i];
    fmi3Status s = fmi3OK;
    fmi3ValueReference vr[4], u[4];
    size_t n_vr, n_u;
    double x[MAX_VALUES], y[MAX_VALUES];
    fmi3Boolean event, terminate, early;
    fmi3Float64 last;
    size_t nx = refs(sane, inputs, n_in, vr, &n_vr);
    for (size_t j = 0; j < MAX_VALUES; j++)
        x[j] = sane && pick(10) ? 1e-3 * ((double)pick(2001) - 1000.0) : value();
    switch (op) {
    case 1:
        s = fmi3EnterInitializationMode(c, fmi3False, 0.0, pick(4) ? 0.0 : value(), (fmi3Boolean)pick(2), value());
        break;
    case 2:
        s = fmi3ExitInitializationMode(c);
        r->t[i] = 0.0;
        break;
    case 3:
    case 4:
        s = fmi3SetFloat64(c, vr, n_vr, x, nx);
        break;
    case 5: {
        fmi3Int32 v[MAX_VALUES];
        for (size_t j = 0; j < MAX_VALUES; j++)
            v[j] = pick(3) ? pick(4) : (fmi3Int32)next();
        s = fmi3SetInt32(c, vr, n_vr, v, nx);
        break;
    }
    case 6: {
        size_t ny = refs(sane, outputs, n_out, u, &n_u);
        s = fmi3GetFloat64(c, u, n_u, y, ny);
        break;
    }
    case 7: {
        fmi3Int32 v[MAX_VALUES];
        s = fmi3GetInt32(c, vr, n_vr, v, nx);
        break;
    }
    case 8:
    case 9:
    case 10: { /* doStep: mostly where the FMU is, sometimes anywhere */
        double H = pick(8) ? 0.01 * (1 + pick(3)) : value();
        for (int j = 0; j < 20 && sane && pick(4); j++) { /* a few steps in a row */
            if (fmi3DoStep(c, r->t[i], H, fmi3True, &event, &terminate, &early, &last) != fmi3OK)
                break;
            r->t[i] += H;
            r->steps_ok++;
        }
        double tc = pick(8) ? r->t[i] : value();
        s = fmi3DoStep(c, tc, H, fmi3True, &event, &terminate, &early, &last);
        if (s == fmi3OK) {
            r->t[i] = tc + H;
            r->steps_ok++;
        }
        break;
    }
    case 11:
        s = fmi3GetFMUState(c, &r->states[i]);
        break;
    case 12: { /* a state of any instance into this one */
        int j = pick(N_INST);
        if (r->states[j])
            s = fmi3SetFMUState(c, r->states[j]);
        r->restored_ok += s == fmi3OK && r->states[j];
        break;
    }
    case 13: { /* serialize, maybe damage, deserialize, set */
        if (!r->states[i])
            break;
        size_t size = 0;
        if (fmi3SerializedFMUStateSize(c, r->states[i], &size) != fmi3OK)
            break;
        free(r->blob);
        r->blob = malloc(size ? size : 1);
        if (!r->blob || fmi3SerializeFMUState(c, r->states[i], r->blob, size) != fmi3OK)
            break;
        if (pick(2) && size)
            r->blob[pick((int)size)] ^= (unsigned char)(1 + pick(255));
        fmi3FMUState other = NULL;
        size_t given = pick(5) ? size : (size_t)pick((int)size + 1);
        s = fmi3DeserializeFMUState(c, r->blob, given, &other);
        if (s == fmi3OK) {
            s = fmi3SetFMUState(c, other);
            fmi3FreeFMUState(c, &other);
        }
        break;
    }
    case 14:
    case 15: { /* directional or adjoint derivative of anything */
        size_t ny = refs(sane, outputs, n_out, u, &n_u);
        int step = pick(2); /* FMI's partial derivatives at the communication point, or the last step's (docs/fmu.md) */
        if (op == 14) {
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
    case 16: /* the whole start-up in one go */
        fmi3EnterInitializationMode(c, fmi3False, 0.0, 0.0, fmi3False, 0.0);
        s = fmi3ExitInitializationMode(c);
        r->t[i] = 0.0;
        break;
    case 17: { /* what this FMU does not provide */
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
    default:
        switch (pick(3)) {
        case 0:
            s = fmi3Reset(c);
            r->t[i] = 0.0;
            break;
        case 1:
            s = fmi3Terminate(c);
            break;
        default:
            s = fmi3SetDebugLogging(c, (fmi3Boolean)pick(2), 0, NULL);
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
    path = argv[1];
    token = argv[2];
    const fuzz_api api = {19, fmi3Error, 1, instantiate, free_instance, free_state, call};
    return fuzz_main(&api, strtoull(argv[3], NULL, 10), atol(argv[4]));
}
