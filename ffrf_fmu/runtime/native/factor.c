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
 * Within I_e the velocity unknowns V (v0, Omega0, r: nv) go first, by the structure of their rows: (69b), (69d)
 * and k_q (79) depend on the velocities only through -v0, -Omega0 and -M_bar r (superelement.c), so
 * J[V, V] = -beta diag(I_6, M_bar) for every state, inverted through M_bar's LU made at creation (accel.c
 * `ffrf_mass_factors`). With Z = I_e \ V (x0, Theta0, eta rates: 6 + nm) and O = Z + B_e:
 *     X = J[V, V]^-1 J[V, O],  J'[O, O] = J[O, O] - J[O, V] X,
 * and A_e, C_e, R_e above are those of J' on Z (nz = 6 + nm); back: x_V = J[V, V]^-1 b_V - X x_O. The k_q
 * rows of JT come premultiplied by M_bar^-1 (ffrf_evaluate: M_bar^-1 k_q's blocks are Dq + beta Dqd T [+ the
 * Coriolis part through M_bar^-1 G_k, made at creation]), so X is J[V, O] times -1/beta, and it is sparse (Dq's
 * pattern): the dense work is the product with J[O, V] over X's nonzeros, at most (nz + m_e)^2 nv, in place of
 * an LU of n_int^3 / 3 and the m_e n_int^2 of A_e^-1 C_e (4 SE x 6 modes: n_int = 36, nz = 12). J[V, V] itself
 * is never read (nor written by ffrf_evaluate); the solve applies J[V, V]^-1 = -1/beta diag(I_6, M_bar^-1) to b.
 * Each A_e (nz^2, partial pivoting within it) and S (n_bnd^2, partial pivoting) is factored densely
 * (`ffrf_lu_factor` of lu.c, LAPACK's dgetf2). The result agrees with the dense LU (scipy's lu_factor on the
 * numpy path) to round-off times the condition number.
 *
 * The factors are stored in the body's nf x nf factorization buffer, pivots in its nf pivots (E blocks of
 * n_int, the first nz of each used, then n_bnd for S); with m_e <= n_bnd the free boundary dofs of e, they fit:
 * sum_e (nz^2 + 2 nz m_e + 2 (nz + m_e) nv) + n_bnd^2 + 1 <= (E n_int + n_bnd)^2. Layout:
 *     per e: LU(A_e)^T [nz][nz] | W_e = A_e^-1 C_e [m_e][nz] (column k of A_e^-1 C_e in row k) | R_e [m_e][nz]
 *            | X [nz + m_e][nv] (column o of X in row o) | J[O, V]^T [nv][nz + m_e];
 *     then LU(S)^T [n_bnd][n_bnd], then -1/beta.
 * The partition (which Newton positions are whose) is body.c `partition`. */
#include "factor.h"
#include "lu.h"

/* No fused multiply-adds: the eliminations' sums as written, as in lu.c. */
#if defined(__clang__)
#pragma STDC FP_CONTRACT OFF
#endif

/* J[row][col] from the transposed iteration matrix JT (JT[col][row]), Newton positions */
#define J(row, col) JT[(size_t)(col) * nf + (size_t)(row)]

/* The free boundary dofs of superelement e (their index among the node unknowns, part.se_fb) into *fb; their count. */
static int free_boundary(const ffrf_body *b, int e, const idx_t **fb)
{
    *fb = b->part.se_fb + (size_t)e * b->dims.n_be;
    return (int)b->part.se_m[e];
}

void ffrf_factor_prepare(ffrf_body *b)
{
    const ffrf_dims *d = &b->dims;
    const size_t nv = (size_t)d->nv, nz = (size_t)(d->n_int - d->nv), nB = (size_t)d->n_bnd;
    size_t blocks = 0; /* the superelements' blocks, then S and -1/beta */
    for (int e = 0; e < d->E; e++) {
        const idx_t *be = b->part.se_bnd + (size_t)e * d->n_be;
        idx_t *fb = b->part.se_fb + (size_t)e * d->n_be;
        int m = 0;
        for (int k = 0; k < d->n_be; k++)
            if (be[k] >= 0)
                fb[m++] = be[k];
        b->part.se_m[e] = m;
        blocks += nz * nz + 2 * (size_t)m * nz + 2 * (nz + (size_t)m) * nv;
    }
    b->part.entries = blocks + nB * nB + 1;
}

size_t ffrf_factor_entries(const ffrf_body *b) { return b->part.entries; }

/* Zero J[B, B], the boundary nodes' block, the one that several parts add into (the superelements sharing a
 * node, the springs, the loads); ffrf_evaluate sets every other entry that ffrf_factor reads (J[I_e, I_e],
 * J[I_e, B_e], J[B_e, I_e]: superelement e's alone), and no other entry is written. */
void ffrf_factor_clear(const ffrf_body *b, double *JT)
{
    const int nf = b->dims.nf, nB = b->dims.n_bnd;
    const idx_t *B = b->part.node_unknowns;
    for (int j = 0; j < nB; j++)
        for (int i = 0; i < nB; i++)
            J(B[i], B[j]) = 0.0;
}

/* 1 when every value is finite: x - x is 0 for a finite x, NaN for an infinite or NaN one. */
static int all_finite(const double *x, size_t n)
{
    double s[4] = {0.0, 0.0, 0.0, 0.0}; /* four sums: not one chain of additions' latency */
    size_t i = 0;
    for (; i + 3 < n; i += 4)
        for (int k = 0; k < 4; k++)
            s[k] += x[i + k] - x[i + k];
    for (; i < n; i++)
        s[0] += x[i] - x[i];
    return s[0] + s[1] + s[2] + s[3] == 0.0;
}

/* u <- A_vv^-1 u for one superelement's velocity unknowns u [nv]: A_vv = -beta diag(I_6, M_bar) (c = -1/beta),
 * M_bar^-1 made at creation (b->work.M_inv; a product, not M_bar's two triangular solves: a third of their time
 * at n = 15). */
static void velocity_solve(const ffrf_body *b, int e, double c, double *u)
{
    const int n = b->dims.n;
    const double *inv = b->work.M_inv + (size_t)e * n * n;
    double *t = b->part.u;
    for (int i = 0; i < n; i++)
        t[i] = 0.0;
    for (int j = 0; j < n; j++)
        ffrf_axpy(n, u[6 + j], inv + (size_t)j * n, t);
    for (int i = 0; i < 6; i++)
        u[i] *= c;
    for (int i = 0; i < n; i++)
        u[6 + i] = c * t[i];
}

static double dot(int n, const double *restrict x, const double *restrict y)
{
    double s = 0.0;
    for (int i = 0; i < n; i++)
        s += x[i] * y[i];
    return s;
}

int ffrf_factor(const ffrf_body *b, const double *JT, double beta, double *store, int *piv)
{
    const ffrf_dims *d = &b->dims;
    const int nf = d->nf, ni = d->n_int, nv = d->nv, nz = ni - nv, nB = d->n_bnd;
    const idx_t *I = b->part.se_unknowns, *B = b->part.node_unknowns;
    const double c = -1.0 / beta;
    double *col = b->part.y; /* [nz + m_e] <= [n_int]: a column of J[O, O] - J[O, V] X */
    const idx_t *fb;
    double *A = store; /* the blocks of the superelements, one after the other; then S, then c */
    size_t blocks = ffrf_factor_entries(b) - (size_t)nB * nB - 1;
    double *S = store + blocks;
    for (int j = 0; j < nB; j++) /* S = D, transposed */
        for (int i = 0; i < nB; i++)
            S[(size_t)j * nB + i] = J(B[i], B[j]);
    S[(size_t)nB * nB] = c;
    if (!all_finite(S, (size_t)nB * nB))
        return -1;
    for (int e = 0; e < d->E; e++) {
        const idx_t *Z = I + (size_t)e * ni, *V = Z + nz;
        const int m = free_boundary(b, e, &fb), no = nz + m;
        double *W = A + (size_t)nz * nz, *R = W + (size_t)m * nz, *X = R + (size_t)m * nz, *PT = X + (size_t)no * nv;
#define OUTER(o) ((o) < nz ? Z[o] : B[fb[(o) - nz]])
        for (int o = 0; o < no; o++) { /* X = J[V, O] by columns (then A_vv^-1 X), PT = J[O, V]^T by rows */
            const idx_t Oo = OUTER(o);
            double *x = X + (size_t)o * nv;
            for (int i = 0; i < nv; i++) {
                x[i] = J(V[i], Oo);
                PT[(size_t)i * no + o] = J(Oo, V[i]);
            }
        }
        if (!all_finite(X, 2 * (size_t)no * nv))
            return -1;
        for (size_t i = 0; i < (size_t)no * nv; i++) /* A_vv^-1 X: the k_q rows come solved by M_bar (ffrf_evaluate) */
            X[i] *= c;
        /* J'[O, O] = J[O, O] - J[O, V] X column by column: A_e (Z, Z), R_e (B, Z), C_e (Z, B: into W), S (B, B) */
        for (int o2 = 0; o2 < no; o2++) {
            const idx_t O2 = OUTER(o2);
            const double *x = X + (size_t)o2 * nv;
            const double *Jc = JT + (size_t)O2 * nf; /* column O2 of J */
            for (int o = 0; o < nz; o++)
                col[o] = Jc[Z[o]];
            for (int k = 0; k < m; k++) /* (S's entries start from 0: they hold D and the other superelements' part) */
                col[nz + k] = o2 < nz ? Jc[B[fb[k]]] : 0.0;
            for (int i = 0; i < nv; i++) /* (X is sparse: Dq + beta Dqd's nonzeros; PT is finite, a zero adds nothing) */
                if (x[i] != 0.0)
                    ffrf_axmy(no, x[i], PT + (size_t)i * no, col);
            if (o2 < nz) {
                for (int i = 0; i < nz; i++)
                    A[(size_t)o2 * nz + i] = col[i];
                for (int k = 0; k < m; k++)
                    R[(size_t)k * nz + o2] = col[nz + k];
            } else {
                for (int i = 0; i < nz; i++)
                    W[(size_t)(o2 - nz) * nz + i] = col[i];
                for (int k = 0; k < m; k++) /* row fb_k, column fb_(o2 - nz) */
                    S[(size_t)fb[o2 - nz] * nB + fb[k]] += col[nz + k];
            }
        }
#undef OUTER
        /* (the LU takes a NaN pivot for nonzero: a non-finite J[Z, Z], J[Z, B] or J[B, Z] is refused here, -1) */
        if (!all_finite(A, (size_t)nz * nz) || !all_finite(R, (size_t)m * nz) || !all_finite(W, (size_t)m * nz))
            return -1;
        if (ffrf_lu_factor(A, piv + (size_t)e * ni, nz) != 0)
            return -1;
        for (int j = nz; j < ni; j++) /* (unused: the pivots keep the layout of E blocks of n_int, body.c's state check) */
            piv[(size_t)e * ni + j] = j;
        for (int k = 0; k < m; k++)
            ffrf_lu_solve(A, piv + (size_t)e * ni, W + (size_t)k * nz, nz);
        for (int k = 0; k < m; k++) /* S[fb_k, fb_l] -= R_e[k] . W_e[l] */
            for (int l = 0; l < m; l++)
                S[(size_t)fb[l] * nB + fb[k]] -= dot(nz, R + (size_t)k * nz, W + (size_t)l * nz);
        A = PT + (size_t)no * nv;
    }
    return ffrf_lu_factor(S, piv + (size_t)d->E * ni, nB) != 0 ? -1 : 0;
}

void ffrf_factor_solve(const ffrf_body *b, const double *store, const int *piv, double *x)
{
    const ffrf_dims *d = &b->dims;
    const int ni = d->n_int, nv = d->nv, nz = ni - nv, nB = d->n_bnd;
    const idx_t *I = b->part.se_unknowns, *B = b->part.node_unknowns;
    double *y = b->part.y, *xB = b->part.xB, *t = b->part.t;
    const double *S = store + ffrf_factor_entries(b) - (size_t)nB * nB - 1, c = S[(size_t)nB * nB];
    const idx_t *fb;
    const double *A = store;
    for (int e = 0; e < d->E; e++) { /* y_v = A_vv^-1 b_v kept in x[V]; b_O -= P y_v */
        const idx_t *Z = I + (size_t)e * ni, *V = Z + nz;
        const int m = free_boundary(b, e, &fb), no = nz + m;
        const double *PT = A + (size_t)nz * nz + 2 * (size_t)m * nz + (size_t)no * nv;
        for (int i = 0; i < nv; i++)
            y[i] = x[V[i]];
        velocity_solve(b, e, c, y);
        for (int o = 0; o < no; o++)
            t[o] = 0.0;
        for (int i = 0; i < nv; i++) {
            x[V[i]] = y[i];
            ffrf_axpy(no, y[i], PT + (size_t)i * no, t);
        }
        for (int o = 0; o < nz; o++)
            x[Z[o]] -= t[o];
        for (int k = 0; k < m; k++)
            x[B[fb[k]]] -= t[nz + k];
        A = PT + (size_t)no * nv;
    }
    for (int i = 0; i < nB; i++)
        xB[i] = x[B[i]];
    A = store;
    for (int e = 0; e < d->E; e++) { /* y_e = A_e^-1 b_e kept in x[Z]; b_B -= R_e y_e */
        const idx_t *Z = I + (size_t)e * ni;
        const int m = free_boundary(b, e, &fb), no = nz + m;
        const double *R = A + (size_t)nz * nz + (size_t)m * nz;
        for (int i = 0; i < nz; i++)
            y[i] = x[Z[i]];
        ffrf_lu_solve(A, piv + (size_t)e * ni, y, nz);
        for (int i = 0; i < nz; i++)
            x[Z[i]] = y[i];
        for (int k = 0; k < m; k++)
            xB[fb[k]] -= dot(nz, R + (size_t)k * nz, y);
        A = R + (size_t)m * nz + 2 * (size_t)no * nv;
    }
    ffrf_lu_solve(S, piv + (size_t)d->E * ni, xB, nB);
    for (int i = 0; i < nB; i++)
        x[B[i]] = xB[i];
    A = store;
    for (int e = 0; e < d->E; e++) { /* x_Z = y_Z - W_e x_B, then x_V = y_v - X x_O */
        const idx_t *Z = I + (size_t)e * ni, *V = Z + nz;
        const int m = free_boundary(b, e, &fb), no = nz + m;
        const double *W = A + (size_t)nz * nz, *X = W + 2 * (size_t)m * nz;
        for (int i = 0; i < nz; i++) /* x_O into t */
            t[i] = x[Z[i]];
        for (int k = 0; k < m; k++) {
            ffrf_axmy(nz, xB[fb[k]], W + (size_t)k * nz, t);
            t[nz + k] = xB[fb[k]];
        }
        for (int i = 0; i < nz; i++)
            x[Z[i]] = t[i];
        for (int i = 0; i < nv; i++)
            y[i] = x[V[i]];
        for (int o = 0; o < no; o++)
            ffrf_axmy(nv, t[o], X + (size_t)o * nv, y);
        for (int i = 0; i < nv; i++)
            x[V[i]] = y[i];
        A = X + 2 * (size_t)no * nv;
    }
}
