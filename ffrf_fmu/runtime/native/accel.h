/* What accel.c offers the layers above it: ports' true accelerations. */
#ifndef FFRF_ACCEL_H
#define FFRF_ACCEL_H

#include "layout.h"

/* ---- accel.c: a port's true accelerations at the end of the step (runtime/accelerations.py) ---- */
void ffrf_port_accelerations(const ffrf_body *b, int port, double a[3], double dw[3]);
int ffrf_mass_factors(ffrf_body *b);

#endif
