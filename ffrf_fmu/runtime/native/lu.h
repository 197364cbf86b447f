/* What lu.c offers the layers above it: the dense LU with partial pivoting and its solve. */
#ifndef FFRF_LU_H
#define FFRF_LU_H

/* ---- lu.c: dense LU with partial pivoting (LAPACK dgetf2), A stored transposed ---- */
/* The LU of the n x n matrix aT (transposed) in place, row interchanges into piv (0-based): 0, or j + 1 for the
 * first exactly zero pivot (LAPACK's info). */
int ffrf_lu_factor(double *aT, int *piv, int n);
/* b <- A^-1 b from ffrf_lu_factor's luT and piv (LAPACK getrs' order). */
void ffrf_lu_solve(const double *luT, const int *piv, double *b, int n);
/* y += a x and y -= a x (n entries, x and y not overlapping), the inner loops of both, two entries at a time. */
void ffrf_axpy(int n, double a, const double *restrict x, double *restrict y);
void ffrf_axmy(int n, double a, const double *restrict x, double *restrict y);

#endif
