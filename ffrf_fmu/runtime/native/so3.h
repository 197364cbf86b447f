/* What so3.c offers the layers above it: rotation helpers. */
#ifndef FFRF_SO3_H
#define FFRF_SO3_H

#include "layout.h"

/* ---- so3.c: the rotation helpers (runtime/rotation.py) ---- */
void ffrf_expm(const double th[3], double out[9]);
void ffrf_tangent(const double th[3], double out[9]);
void ffrf_logm(const double M[9], double out[3]);
void ffrf_inv3(const double A[9], double out[9]);
void ffrf_skew(const double a[3], double out[9]);
void ffrf_cross(const double a[3], const double b[3], double out[3]);

#endif
