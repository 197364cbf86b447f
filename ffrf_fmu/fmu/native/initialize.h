/* What initialize.c offers the model above it: a body's consistent initial state at t0 (BodySystem.initialize on
 * the C runtime's body) and the start state made at build. */
#ifndef FFRF_FMU_INITIALIZE_H
#define FFRF_FMU_INITIALIZE_H

#include <stddef.h>

#include "ffrf_runtime.h"

/* The consistent initial state from the point values at t0 and the parameters (BodySystem.initialize): 0, or
 * non-zero with err naming the cause. */
int fmu_initialize_body(ffrf_body *b, double t0, const double velocity[3], const double angular_velocity[3],
                        const double origin[3], const double *port_displacements, const char *const *port_names,
                        char *err, size_t err_len);

/* The start state made at build (runtime/start.py) taken at t0 by a body just initialized: 0, or -1
 * with err naming the cause. */
int fmu_start_body(ffrf_body *b, double t0, const double *start, size_t count, const char *const *port_names,
                   char *err, size_t err_len);

#endif
