/* What advance.c offers the layers above it: inputs by kind, output rows, many steps. */
#ifndef FFRF_ADVANCE_H
#define FFRF_ADVANCE_H

#include "layout.h"

/* ---- advance.c: inputs by kind, output rows, many steps in one call ---- */
void ffrf_scheduled_inputs(ffrf_body *b, double t, double h);
void ffrf_extrapolated_inputs(ffrf_body *b, double t, double t_c);
/* One output row (simulate.record's layout): per port r, R, v, w, f, t, a, dw (FFRF_OUTPUT_WIDTH), then kinetic_rigid,
 * kinetic_elastic, strain, work_external, iterations. */
void ffrf_record(const ffrf_body *b, double *row);

#endif
