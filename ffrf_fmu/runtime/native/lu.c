/* Dense linear algebra: the LU with partial pivoting (LAPACK's dgetf2) and its triangular solves, the one
 * home of both. factor.c factors the iteration matrix's blocks with it, accel.c each superelement's M_bar.
 * Matrices are stored transposed (column-major, as LAPACK wants them). */
#include <math.h>
#include <stddef.h>

#include "lu.h"

/* No fused multiply-adds: the LU must match LAPACK's (scipy's) to round-off, as the equations do. */
#if defined(__clang__)
#pragma STDC FP_CONTRACT OFF
#endif

/* LU of the n x n matrix A in place, A stored transposed (aT[col][row] = A[row][col], i.e. A in
 * column-major order as LAPACK wants it), row interchanges into piv (0-based). LAPACK's unblocked
 * dgetf2, step for step: column j's pivot is the first entry of largest |a| on or below the diagonal
 * (idamax), the whole rows are swapped, the column below the pivot scaled by 1/pivot (dscal; divided
 * when |pivot| < the safe minimum), then the rank-1 update of the trailing matrix column by column
 * (dger with alpha = -1). Returns 0, or j + 1 for the first exactly zero pivot (LAPACK's info; the
 * factorization then is not usable). Replaces dgetrf (scipy's lu_factor), which runs this algorithm
 * blocked: the factors agree to round-off. */
int ffrf_lu_factor(double *aT, int *piv, int n)
{
    const double sfmin = 2.2250738585072014e-308; /* dlamch('S'): DBL_MIN (1/DBL_MAX is smaller) */
    int info = 0;
    for (int j = 0; j < n; j++) {
        double *colj = aT + (size_t)j * n;
        int jp = j;
        double amax = fabs(colj[j]);
        for (int i = j + 1; i < n; i++) { /* idamax: the first of the largest */
            double a = fabs(colj[i]);
            if (a > amax) {
                amax = a;
                jp = i;
            }
        }
        piv[j] = jp;
        if (colj[jp] != 0.0) {
            if (jp != j)
                for (int k = 0; k < n; k++) { /* dswap of rows j and jp */
                    double *ck = aT + (size_t)k * n;
                    double tmp = ck[j];
                    ck[j] = ck[jp];
                    ck[jp] = tmp;
                }
            if (fabs(colj[j]) >= sfmin) {
                double r = 1.0 / colj[j];
                for (int i = j + 1; i < n; i++)
                    colj[i] *= r;
            } else {
                for (int i = j + 1; i < n; i++)
                    colj[i] = colj[i] / colj[j];
            }
        } else if (info == 0) {
            info = j + 1;
        }
        for (int k = j + 1; k < n; k++) { /* dger: A[j+1:, j+1:] -= A[j+1:, j] A[j, j+1:] */
            double *ck = aT + (size_t)k * n;
            double temp = -ck[j];
            if (temp != 0.0) /* (dger skips a zero column of y) */
                ffrf_axpy(n - j - 1, temp, colj + j + 1, ck + j + 1);
        }
    }
    return info;
}

/* Solve J x = b in place from the LU of J (luT = the factors, transposed; piv 0-based), in
 * LAPACK getrs' order (the numpy path calls dgetrs: the interchanges, the unit lower triangle, the upper). */
void ffrf_lu_solve(const double *luT, const int *piv, double *b, int n)
{
    for (int i = 0; i < n; i++) {
        int k = piv[i];
        if (k != i) {
            double tmp = b[i];
            b[i] = b[k];
            b[k] = tmp;
        }
    }
    for (int j = 0; j < n; j++) { /* unit lower triangle, column by column: L[i, j] = luT[j, i] */
        const double *row = luT + (size_t)j * n;
        ffrf_axmy(n - j - 1, b[j], row + j + 1, b + j + 1);
    }
    for (int j = n - 1; j >= 0; j--) { /* upper triangle */
        const double *row = luT + (size_t)j * n;
        b[j] /= row[j];
        ffrf_axmy(j, b[j], row, b);
    }
}
