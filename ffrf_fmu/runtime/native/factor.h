/* What factor.c offers the layers above it: dense LU and the iteration matrix factored by its structure. */
#ifndef FFRF_FACTOR_H
#define FFRF_FACTOR_H

#include "layout.h"

/* ---- factor.c: dense LU with partial pivoting (LAPACK dgetf2), A stored transposed ---- */
int ffrf_lu_factor(double *aT, int *piv, int n);
void ffrf_lu_solve(const double *luT, const int *piv, double *b, int n);

/* ---- factor.c: the iteration matrix factored by its structure (superelements, then nodes) ---- */
/* The factors of JT [nf][nf] (transposed) into store [nf * nf] and piv [nf]: 0, or -1 when a pivot is
 * exactly zero (not factorable). */
int ffrf_factor(const ffrf_body *b, const double *JT, double *store, int *piv);
/* x <- J^-1 x in the Newton order, from ffrf_factor's store and piv. */
void ffrf_factor_solve(const ffrf_body *b, const double *store, const int *piv, double *x);

#endif
