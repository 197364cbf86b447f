/* The call-sequence driver that tests/fmi2_fuzz.c and tests/fmi3_fuzz.c share: the random source, the
 * values that break things (NaN, inf, huge), the instance slots with their saved states and times, the
 * loop that picks a slot and a call and checks the status, the clean-up and the counts printed at the end.
 * the calls every FMI version has (doStep, the FMU states saved, restored, serialized and damaged, the end
 * of initialization, reset, terminate, logging), main's frame. Each fuzzer gives what is FMI-version-specific (fuzz_api): how to
 * instantiate and free, its own calls by number, and the shared calls as functions of its FMI version. Header-only, included once by each fuzzer (static functions: no symbol clashes). */
#ifndef FUZZ_DRIVER_H
#define FUZZ_DRIVER_H

#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>

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

/* a value for an input: mostly moderate, sometimes NaN, inf or a huge or tiny one */
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

/* the experiment of a start-up call (fmi2SetupExperiment, fmi3EnterInitializationMode; no tolerance): the start
 * mostly 0, else anything; a stop time or none, anything. Drawn in this order (a call's arguments are not). */
typedef struct {
    double start;
    int has_stop;
    double stop;
} fuzz_experiment;

static fuzz_experiment experiment(void)
{
    fuzz_experiment e;
    e.start = pick(4) ? 0.0 : value();
    e.has_stop = pick(2);
    e.stop = value();
    return e;
}

/* an input's value: for a sane call mostly a moderate one */
static double input_value(int sane)
{
    return sane && pick(10) ? 1e-3 * ((double)pick(2001) - 1000.0) : value();
}

#define N_INST 3

/* the instance slots and what the sequences reached */
typedef struct {
    void *inst[N_INST];   /* NULL: no instance in the slot */
    void *states[N_INST]; /* a saved FMU state per slot: one malloc'd block (model.c), free() releases it */
    double t[N_INST];     /* the communication point each instance is at */
    unsigned char *blob;  /* the last serialized state */
    long steps_ok, restored_ok, derivatives_ok, adjoints_ok;
} fuzz_run;

/* What a fuzzer gives: its instantiation, its own calls and the FMI calls every version has (statuses as ints:
 * FMI 2.0's and 3.0's have the same values) */
typedef struct {
    int n_own;                                           /* its own calls 1 .. n_own (call), then the shared ones */
    int error;                                           /* the Error status: 0 .. error are the legal statuses */
    int adjoints;                                        /* print adjoints_ok */
    void *(*instantiate)(void);                          /* a new instance (sometimes with wrong arguments) or NULL */
    void (*free_instance)(void *inst);
    int (*call)(fuzz_run *r, int i, int call, int sane); /* one of its own calls on slot i: its status */
    int (*do_step)(void *inst, double t, double H);
    int (*get_state)(void *inst, void **state);
    int (*set_state)(void *inst, void *state);
    void (*free_state)(void *inst, void **state);
    int (*state_size)(void *inst, void *state, size_t *size);
    int (*serialize)(void *inst, void *state, unsigned char *out, size_t size);
    int (*deserialize)(void *inst, const unsigned char *in, size_t size, void **state);
    int (*exit_initialization)(void *inst);
    int (*reset)(void *inst);
    int (*terminate)(void *inst);
    int (*logging)(void *inst, int on);
    int (*setup)(const char *inputs, const char *outputs); /* main's lists of inputs and outputs taken: 0, or -1 */
} fuzz_api;

/* The calls every version has, written once from the version's names: a fuzzer defines, before it includes
 * this header, FMI_(name) (its prefix: fmi2##name), FMI_STATE_(verb, tail) (fmi2##verb##FMUstate##tail: FMI 3.0
 * spells FMUState) and FMI_DESERIALIZE (fmi2DeSerializeFMUstate, fmi3DeserializeFMUState); its own do_step
 * (fmi3DoStep has more out-arguments). The casts are those of the standard's types (fmi2Byte is char, fmi3Byte
 * uint8_t; fmi2Boolean int, fmi3Boolean bool). */
#ifdef FMI_
static void free_instance(void *c) { FMI_(FreeInstance)(c); }
static int get_state(void *c, void **state) { return (int)FMI_STATE_(Get, )(c, state); }
static int set_state(void *c, void *state) { return (int)FMI_STATE_(Set, )(c, state); }
static void free_state(void *c, void **state) { FMI_STATE_(Free, )(c, state); }
static int state_size(void *c, void *state, size_t *size) { return (int)FMI_STATE_(Serialized, Size)(c, state, size); }
static int serialize(void *c, void *state, unsigned char *out, size_t size)
{
    return (int)FMI_STATE_(Serialize, )(c, state, (FMI_(Byte) *)out, size);
}
static int deserialize(void *c, const unsigned char *in, size_t size, void **state)
{
    return (int)FMI_DESERIALIZE(c, (const FMI_(Byte) *)in, size, state);
}
static int exit_initialization(void *c) { return (int)FMI_(ExitInitializationMode)(c); }
static int reset(void *c) { return (int)FMI_(Reset)(c); }
static int terminate(void *c) { return (int)FMI_(Terminate)(c); }
static int logging(void *c, int on) { return (int)FMI_(SetDebugLogging)(c, (FMI_(Boolean))on, 0, NULL); }
#endif

/* a fuzzer's fuzz_api from its functions of these names */
#define FUZZ_API(n_own, error, adjoints)                                                                         \
    {(n_own),     (error),     (adjoints), instantiate, free_instance,       call,  do_step,   get_state, \
     set_state,   free_state,  state_size, serialize,   deserialize, exit_initialization, reset, terminate, logging,   \
     setup}

static const char *fuzz_location, *fuzz_token; /* the FMU under test: main's arguments 1 and 2 */

/* a fuzzer's setup (its parse_list of main's lists into its inputs and outputs) and its main */
#define FUZZ_MAIN(n_own, error, adjoints)                                                                        \
    static int setup(const char *in, const char *out)                                                           \
    {                                                                                                           \
        n_in = parse_list(in, inputs, MAX_VR);                                                                  \
        n_out = parse_list(out, outputs, MAX_VR);                                                               \
        return n_in && n_out ? 0 : -1;                                                                          \
    }                                                                                                           \
    int main(int argc, char **argv)                                                                             \
    {                                                                                                           \
        const fuzz_api api = FUZZ_API(n_own, error, adjoints);                                                  \
        return fuzz_main(&api, argc, argv);                                                                     \
    }

#define N_SHARED 8 /* the calls of every version: doStep (3 ways), get, set and serialize states, the end of
                    * initialization, the rest (reset, terminate, logging: the default arm) */

/* one of the shared calls k (0 .. N_SHARED - 1) on slot i: its status */
static int shared_call(const fuzz_api *api, fuzz_run *r, int i, int k, int sane)
{
    void *c = r->inst[i];
    int s = 0;
    switch (k) {
    case 0:
    case 1:
    case 2: { /* doStep: mostly where the FMU is, sometimes anywhere */
        double H = pick(8) ? 0.01 * (1 + pick(3)) : value();
        for (int j = 0; j < 20 && sane && pick(4); j++) { /* a few steps in a row */
            if (api->do_step(c, r->t[i], H) != 0)
                break;
            r->t[i] += H;
            r->steps_ok++;
        }
        double tc = pick(8) ? r->t[i] : value();
        s = api->do_step(c, tc, H);
        if (s == 0) {
            r->t[i] = tc + H;
            r->steps_ok++;
        }
        break;
    }
    case 3:
        s = api->get_state(c, &r->states[i]);
        break;
    case 4: { /* a state of any instance into this one (only its own FMU's states exist here) */
        int j = pick(N_INST);
        if (r->states[j])
            s = api->set_state(c, r->states[j]);
        r->restored_ok += s == 0 && r->states[j];
        break;
    }
    case 5: { /* serialize, maybe damage, deserialize, set */
        if (!r->states[i])
            break;
        size_t size = 0;
        if (api->state_size(c, r->states[i], &size) != 0)
            break;
        free(r->blob);
        r->blob = malloc(size ? size : 1);
        if (!r->blob || api->serialize(c, r->states[i], r->blob, size) != 0)
            break;
        if (pick(2) && size)
            r->blob[pick((int)size)] ^= (unsigned char)(1 + pick(255));
        void *other = NULL;
        size_t given = pick(5) ? size : (size_t)pick((int)size + 1);
        s = api->deserialize(c, r->blob, given, &other);
        if (s == 0) {
            s = api->set_state(c, other);
            api->free_state(c, &other);
        }
        break;
    }
    case 6:
        s = api->exit_initialization(c);
        r->t[i] = 0.0;
        break;
    default:
        switch (pick(3)) {
        case 0:
            s = api->reset(c);
            r->t[i] = 0.0;
            break;
        case 1:
            s = api->terminate(c);
            break;
        default:
            s = api->logging(c, pick(2));
        }
    }
    return s;
}

/* main: FUZZER LOCATION TOKEN SEED CALLS INPUTS OUTPUTS, `CALLS` random calls; returns the process status (0, 2
 * for unusable arguments, or 3 for a status outside OK .. Error) */
static int fuzz_main(const fuzz_api *api, int argc, char **argv)
{
    if (argc < 7 || api->setup(argv[5], argv[6]) != 0)
        return 2;
    fuzz_location = argv[1];
    fuzz_token = argv[2];
    const uint64_t seed = strtoull(argv[3], NULL, 10);
    const long calls = atol(argv[4]);
    fuzz_run r = {{NULL}, {NULL}, {0.0}, NULL, 0, 0, 0, 0};
    long count[8] = {0};
    rng ^= seed * 0x9E3779B97F4A7C15ull;
    for (long k = 0; k < calls; k++) {
        int i = pick(N_INST);
        int sane = pick(4) != 0; /* mostly the FMU's own references with moderate values: the runs get somewhere */
        int call = r.inst[i] ? pick(1 + api->n_own + N_SHARED) : 0;
        if (call == 0) { /* (re)instantiate; a state needs no instance to be freed: it is a malloc'd block */
            if (r.inst[i])
                api->free_instance(r.inst[i]);
            free(r.states[i]);
            r.states[i] = NULL;
            r.inst[i] = api->instantiate();
            r.t[i] = 0.0;
            continue;
        }
        int s = call <= api->n_own ? api->call(&r, i, call, sane) : shared_call(api, &r, i, call - 1 - api->n_own, sane);
        if (s < 0 || s > api->error) {
            fprintf(stderr, "call %ld (%d): status %d\n", k, call, s);
            return 3;
        }
        count[s]++;
    }
    for (int i = 0; i < N_INST; i++) {
        if (r.inst[i] && r.states[i])
            api->free_state(r.inst[i], &r.states[i]);
        free(r.states[i]);
        if (r.inst[i])
            api->free_instance(r.inst[i]);
    }
    free(r.blob);
    printf("ok %ld discard %ld error %ld steps_ok %ld restored_ok %ld derivatives_ok %ld", count[0], count[2], count[3],
           r.steps_ok, r.restored_ok, r.derivatives_ok);
    if (api->adjoints)
        printf(" adjoints_ok %ld", r.adjoints_ok);
    printf("\n");
    return 0;
}

#endif
