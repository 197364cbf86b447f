/* The factorization of the iteration matrix, by its structure: each superelement's own unknowns first,
 * then the boundary nodes.
 *
 * The Newton unknowns of a chain split into the internal unknowns of each superelement e (its CM frame
 * rates, modal rates and velocity rates: n_int = 6 + nm + nv, all free) and the free boundary-node
 * rates (n_bnd), shared by neighbours. Superelement e's equations touch its own internals and its own
 * boundary nodes only, so with I_e its internals and B the nodes
 *
 *     J = [ A_1          C_1 ]      A_e = J[I_e, I_e], C_e = J[I_e, B_e], R_e = J[B_e, I_e],
 *         [      A_2     C_2 ]      B_e the free dofs of e's boundary nodes,
 *         [ R_1  R_2 ...  D  ]      D = J[B, B] (the nodes' own rows: springs, loads, e_P rows)
 *
 * and J x = b is solved by eliminating the internals (static condensation):
 *     S = D - sum_e R_e A_e^-1 C_e,   S x_B = b_B - sum_e R_e A_e^-1 b_e,   x_e = A_e^-1 (b_e - C_e x_B).
 * Each A_e (n_int^2, partial pivoting within it) and S (n_bnd^2, partial pivoting) is factored densely
 * (`ffrf_lu_factor` of lu.c, LAPACK's dgetf2): about E n_int^3 + n_bnd^3 operations where the dense LU of the
 * whole matrix takes (E n_int + n_bnd)^3, 10-20x fewer on chains of 4-8 superelements. The result agrees
 * with the dense LU (scipy's lu_factor on the numpy path) to round-off times the condition number.
 *
 * The factors are stored in the body's nf x nf factorization buffer, pivots in its nf pivots (E n_int
 * for the A_e, n_bnd for S); with m_e <= n_bnd the free boundary dofs of e, they fit:
 * sum_e (n_int^2 + 2 n_int m_e) + n_bnd^2 <= (E n_int + n_bnd)^2. Layout:
 *     per e: LU(A_e)^T [n_int][n_int] | W_e = A_e^-1 C_e [m_e][n_int] (column k of A_e^-1 C_e in row k)
 *            | R_e [m_e][n_int];  then LU(S)^T [n_bnd][n_bnd].
 * The partition (which Newton positions are whose) is body.c `partition`. */
#include "factor.h"
#include "lu.h"

/* No fused multiply-adds: the eliminations' sums as written, as in lu.c. */
#if defined(__clang__)
#pragma STDC FP_CONTRACT OFF
#endif

/* J[row][col] from the transposed iteration matrix JT (JT[col][row]), Newton positions */
#define J(row, col) JT[(size_t)(col) * nf + (size_t)(row)]

/* The free boundary dofs of superelement e (their index among the node unknowns) into fb; their count. */
static int free_boundary(const ffrf_body *b, int e, idx_t *fb)
{
    const idx_t *be = b->part.se_bnd + (size_t)e * b->dims.n_be;
    int m = 0;
    for (int k = 0; k < b->dims.n_be; k++)
        if (be[k] >= 0)
            fb[m++] = be[k];
    return m;
}

/* The entries of the factorization store that ffrf_factor fills: the superelements' blocks and S. */
size_t ffrf_factor_entries(const ffrf_body *b)
{
    const ffrf_dims *d = &b->dims;
    const size_t ni = (size_t)d->n_int, nB = (size_t)d->n_bnd;
    idx_t fb[6 * 64];
    size_t blocks = 0;
    for (int e = 0; e < d->E; e++)
        blocks += ni * ni + 2 * ni * (size_t)free_boundary(b, e, fb);
    return blocks + nB * nB;
}

/* Zero the entries of JT that the structure allows (those ffrf_factor reads: J[I_e, I_e], J[I_e, B_e],
 * J[B_e, I_e], J[B, B]); every other entry is zero by the structure and never written, so this is the
 * memset of the whole nf x nf matrix at the cost of its blocks. */
void ffrf_factor_clear(const ffrf_body *b, double *JT)
{
    const ffrf_dims *d = &b->dims;
    const int nf = d->nf, ni = d->n_int, nB = d->n_bnd;
    const idx_t *I = b->part.se_unknowns, *B = b->part.node_unknowns;
    idx_t fb[6 * 64];
    for (int j = 0; j < nB; j++)
        for (int i = 0; i < nB; i++)
            J(B[i], B[j]) = 0.0;
    for (int e = 0; e < d->E; e++) {
        const idx_t *Ie = I + (size_t)e * ni;
        const int m = free_boundary(b, e, fb);
        for (int j = 0; j < ni; j++)
            for (int i = 0; i < ni; i++)
                J(Ie[i], Ie[j]) = 0.0;
        for (int k = 0; k < m; k++)
            for (int i = 0; i < ni; i++) {
                J(Ie[i], B[fb[k]]) = 0.0;
                J(B[fb[k]], Ie[i]) = 0.0;
            }
    }
}

/* 1 when every value is finite: x - x is 0 for a finite x, NaN for an infinite or NaN one. */
static int all_finite(const double *x, size_t n)
{
    double s = 0.0;
    for (size_t i = 0; i < n; i++)
        s += x[i] - x[i];
    return s == 0.0;
}

int ffrf_factor(const ffrf_body *b, const double *JT, double *store, int *piv)
{
    const ffrf_dims *d = &b->dims;
    const int nf = d->nf, ni = d->n_int, nB = d->n_bnd;
    const idx_t *I = b->part.se_unknowns, *B = b->part.node_unknowns;
    idx_t fb[6 * 64];
    double *A = store; /* the blocks of the superelements, one after the other; then S */
    size_t blocks = 0;
    for (int e = 0; e < d->E; e++)
        blocks += (size_t)ni * ni + 2 * (size_t)ni * free_boundary(b, e, fb);
    double *S = store + blocks;
    for (int j = 0; j < nB; j++) /* S = D, transposed */
        for (int i = 0; i < nB; i++)
            S[(size_t)j * nB + i] = J(B[i], B[j]);
    if (!all_finite(S, (size_t)nB * nB))
        return -1;
    for (int e = 0; e < d->E; e++) {
        const idx_t *Ie = I + (size_t)e * ni;
        const int m = free_boundary(b, e, fb);
        double *W = A + (size_t)ni * ni, *R = W + (size_t)m * ni;
        for (int j = 0; j < ni; j++)
            for (int i = 0; i < ni; i++)
                A[(size_t)j * ni + i] = J(Ie[i], Ie[j]);
        for (int k = 0; k < m; k++) {
            double *w = W + (size_t)k * ni, *r = R + (size_t)k * ni;
            for (int i = 0; i < ni; i++) {
                w[i] = J(Ie[i], B[fb[k]]);
                r[i] = J(B[fb[k]], Ie[i]);
            }
        }
        if (!all_finite(A, (size_t)ni * ni + 2 * (size_t)m * ni) || ffrf_lu_factor(A, piv + (size_t)e * ni, ni) != 0)
            return -1;
        for (int k = 0; k < m; k++)
            ffrf_lu_solve(A, piv + (size_t)e * ni, W + (size_t)k * ni, ni);
        for (int k = 0; k < m; k++) /* S[fb_k, fb_l] -= R_e[k] . W_e[l] */
            for (int l = 0; l < m; l++) {
                double s = 0.0;
                const double *r = R + (size_t)k * ni, *w = W + (size_t)l * ni;
                for (int q = 0; q < ni; q++)
                    s += r[q] * w[q];
                S[(size_t)fb[l] * nB + fb[k]] -= s;
            }
        A = R + (size_t)m * ni;
    }
    return ffrf_lu_factor(S, piv + (size_t)d->E * ni, nB) != 0 ? -1 : 0;
}

void ffrf_factor_solve(const ffrf_body *b, const double *store, const int *piv, double *x)
{
    const ffrf_dims *d = &b->dims;
    const int ni = d->n_int, nB = d->n_bnd;
    const idx_t *I = b->part.se_unknowns, *B = b->part.node_unknowns;
    double *y = b->part.y, *xB = b->part.xB;
    idx_t fb[6 * 64];
    for (int i = 0; i < nB; i++)
        xB[i] = x[B[i]];
    const double *A = store;
    for (int e = 0; e < d->E; e++) { /* y_e = A_e^-1 b_e kept in x[I_e]; b_B -= R_e y_e */
        const idx_t *Ie = I + (size_t)e * ni;
        const int m = free_boundary(b, e, fb);
        const double *R = A + (size_t)ni * ni + (size_t)m * ni;
        for (int i = 0; i < ni; i++)
            y[i] = x[Ie[i]];
        ffrf_lu_solve(A, piv + (size_t)e * ni, y, ni);
        for (int i = 0; i < ni; i++)
            x[Ie[i]] = y[i];
        for (int k = 0; k < m; k++) {
            double s = 0.0;
            const double *r = R + (size_t)k * ni;
            for (int q = 0; q < ni; q++)
                s += r[q] * y[q];
            xB[fb[k]] -= s;
        }
        A = R + (size_t)m * ni;
    }
    ffrf_lu_solve(A, piv + (size_t)d->E * ni, xB, nB); /* A: S, after the blocks */
    A = store;
    for (int e = 0; e < d->E; e++) { /* x_e = y_e - W_e x_B */
        const idx_t *Ie = I + (size_t)e * ni;
        const int m = free_boundary(b, e, fb);
        const double *W = A + (size_t)ni * ni;
        for (int k = 0; k < m; k++) {
            const double *w = W + (size_t)k * ni;
            double xk = xB[fb[k]];
            for (int i = 0; i < ni; i++)
                x[Ie[i]] -= w[i] * xk;
        }
        A = W + 2 * (size_t)m * ni;
    }
    for (int i = 0; i < nB; i++)
        x[B[i]] = xB[i];
}
