/* The call-sequence driver that tests/fmi2_fuzz.c and tests/fmi3_fuzz.c share: the random source, the
 * values that break things (NaN, inf, huge), the instance slots with their saved states and times, the
 * loop that picks a slot and a call and checks the status, the clean-up and the counts printed at the end.
 * Each fuzzer gives what is FMI-version-specific (fuzz_api): how to instantiate, one call by its number,
 * how to free. Header-only, included once by each fuzzer (static functions: no symbol clashes). */
#ifndef FUZZ_DRIVER_H
#define FUZZ_DRIVER_H

#include <math.h>
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

#define N_INST 3

/* the instance slots and what the sequences reached */
typedef struct {
    void *inst[N_INST];   /* NULL: no instance in the slot */
    void *states[N_INST]; /* a saved FMU state per slot: one malloc'd block (model.c), free() releases it */
    double t[N_INST];     /* the communication point each instance is at */
    unsigned char *blob;  /* the last serialized state */
    long steps_ok, restored_ok, derivatives_ok, adjoints_ok;
} fuzz_run;

typedef struct {
    int n_calls;                                         /* calls 1 .. n_calls - 1 on an instance (0 instantiates) */
    int error;                                           /* the Error status: 0 .. error are the legal statuses */
    int adjoints;                                        /* print adjoints_ok */
    void *(*instantiate)(void);                          /* a new instance (sometimes with wrong arguments) or NULL */
    void (*free_instance)(void *inst);
    void (*free_state)(void *inst, void **state);
    int (*call)(fuzz_run *r, int i, int call, int sane); /* one call on slot i: its status */
} fuzz_api;

/* `calls` random calls; returns the process status (0, or 3 for a status outside OK .. Error) */
static int fuzz_main(const fuzz_api *api, uint64_t seed, long calls)
{
    fuzz_run r = {{NULL}, {NULL}, {0.0}, NULL, 0, 0, 0, 0};
    long count[8] = {0};
    rng ^= seed * 0x9E3779B97F4A7C15ull;
    for (long k = 0; k < calls; k++) {
        int i = pick(N_INST);
        int sane = pick(4) != 0; /* mostly the FMU's own references with moderate values: the runs get somewhere */
        int call = r.inst[i] ? pick(api->n_calls) : 0;
        if (call == 0) { /* (re)instantiate; a state needs no instance to be freed: it is a malloc'd block */
            if (r.inst[i])
                api->free_instance(r.inst[i]);
            free(r.states[i]);
            r.states[i] = NULL;
            r.inst[i] = api->instantiate();
            r.t[i] = 0.0;
            continue;
        }
        int s = api->call(&r, i, call, sane);
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
