/* What factor.c offers the layers above it: the iteration matrix factored by its structure. */
#ifndef FFRF_FACTOR_H
#define FFRF_FACTOR_H

#include "layout.h"

/* ---- factor.c: the iteration matrix factored by its structure (superelements, then nodes) ---- */
/* The factors of JT [nf][nf] (transposed), the iteration matrix at beta, into store [nf * nf] and piv [nf]: 0, or -1
 * when an entry it reads is not finite or a pivot is exactly zero (not factorable). */
int ffrf_factor(const ffrf_body *b, const double *JT, double beta, double *store, int *piv);
/* At creation, after the partition: each superelement's free boundary dofs (part.se_fb, se_m) and the entries of
 * the store that ffrf_factor fills (part.entries), fixed for the body's life. */
void ffrf_factor_prepare(ffrf_body *b);
/* The entries of store that ffrf_factor fills (its leading part; the rest is never read). */
size_t ffrf_factor_entries(const ffrf_body *b);
/* JT's boundary-node block J[B, B] set to zero: a refresh's start, before ffrf_evaluate (superelement.c) adds the
 * superelements' parts into it (and sets their own blocks, the other entries ffrf_factor reads). */
void ffrf_factor_clear(const ffrf_body *b, double *JT);
/* x <- J^-1 x in the Newton order, from ffrf_factor's store and piv. */
void ffrf_factor_solve(const ffrf_body *b, const double *store, const int *piv, double *x);

#endif
