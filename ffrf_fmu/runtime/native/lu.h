/* What lu.c offers the layers above it: the dense LU with partial pivoting and its solve, and their vector kernels. */
#ifndef FFRF_LU_H
#define FFRF_LU_H

/* ---- lu.c: dense LU with partial pivoting (LAPACK dgetf2), A stored transposed ---- */
/* The LU of the n x n matrix aT (transposed) in place, row interchanges into piv (0-based): 0, or j + 1 for the
 * first exactly zero pivot (LAPACK's info). */
int ffrf_lu_factor(double *aT, int *piv, int n);
/* b <- A^-1 b from ffrf_lu_factor's luT and piv (LAPACK getrs' order). */
void ffrf_lu_solve(const double *luT, const int *piv, double *b, int n);
/* No fused multiply-adds in the kernels below either (lu.c's pragma comes after this header). */
#if defined(__clang__)
#pragma STDC FP_CONTRACT OFF
#endif

/* y[i] += x[i] a and y[i] -= x[i] a for i < n (x, y not overlapping): the inner loops of the LU, its solve
 * and factor.c's eliminations (inline: their vectors are short, 10-40 entries, and a call per vector
 * cost 15 % of a step of 8 SE x 2 modes), written two entries at a time so that the compiler's SLP
 * vectorizer packs them at -O2 (half the time of the factorization); each entry's operations are those of
 * the plain loop, the results the same bits. */
static inline void ffrf_axpy(int n, double a, const double *restrict x, double *restrict y)
{
    int i = 0;
    for (; i + 1 < n; i += 2) {
        double y0 = y[i] + x[i] * a, y1 = y[i + 1] + x[i + 1] * a;
        y[i] = y0;
        y[i + 1] = y1;
    }
    if (i < n)
        y[i] += x[i] * a;
}

static inline void ffrf_axmy(int n, double a, const double *restrict x, double *restrict y)
{
    int i = 0;
    for (; i + 1 < n; i += 2) {
        double y0 = y[i] - x[i] * a, y1 = y[i + 1] - x[i + 1] * a;
        y[i] = y0;
        y[i + 1] = y1;
    }
    if (i < n)
        y[i] -= x[i] * a;
}

#endif
