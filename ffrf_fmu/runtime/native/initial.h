/* What initial.c offers above it besides ffrf_body_initialize (ffrf_runtime.h): the end of an initialization
 * from a state set as it is (the FMU's start state, fmu/native/initialize.c). */
#ifndef FFRF_INITIAL_H
#define FFRF_INITIAL_H

#include "layout.h"

#define FFRF_RELAX_MAX_ITER 30 /* the relaxation's Newton iterations at most (initial_conditions.py `_relax`) */

/* The port loads at t0 from the point values at t0 (the reactions on motion parts, the springs), the external
 * power, no work done yet, no factorization kept (runtime/start.py `finish`): 0, or -1 out of memory. */
int ffrf_port_loads_at(ffrf_body *b, double t0);

#endif
