/* What step.c offers the layers above it: Newton and the generalized-alpha step. */
#ifndef FFRF_STEP_H
#define FFRF_STEP_H

#include "layout.h"

/* ---- step.c: Newton, the generalized-alpha step, compliant springs ---- */
void ffrf_springs_apply(ffrf_body *b, const double *p, const double *yd, const double *R,
                        const double *T, int jac, double beta, double *F, double *JT);
/* One step t -> t + h (integrator.py `_step`); the state changes only if it succeeded. Returns the
 * status (FFRF_OK ...); b->state.iterations holds its iterations. */
int ffrf_step(ffrf_body *b, double h, int last_it);

#endif
