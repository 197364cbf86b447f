/* The equations of one superelement and their assembly into the body's residual and iteration
 * matrix: the C twin of runtime/equations.py `residual_and_jacobian` with runtime/stiffening.py (`_stiff_force`, `_stiff_tangent`,
 * `_jacobian` and `_evaluate` (runtime/equations.py is the oracle; equation numbers are those of
 * Geradin's two-field paper, docs/equations.md).
 *
 * The loops keep the order of every sum of the equations, statement by statement (a C sum `s += a + b` is
 * s + (a + b) as in Python), so that the C runtime agrees with the numpy path to round-off
 * (tests/test_native_runs.py: 1e-10 of each kinematic field). Build without floating-point contraction
 * (gcc's default in ISO mode, -std=c11; clang needs -ffp-contract=off): a fused multiply-add rounds once
 * where the numpy path rounds twice.
 *
 * Arrays are viewed through pointers to variably modified types (double (*)[n]) so that indexing
 * reads like numpy's (GW[i][j] for GW[i, j]); nothing is allocated here.
 *
 * Term sets: `linear` (gyro = 0), `gyroscopic` (gyro = CORIOLIS | COUPLING), `full`
 * (either part of gyro, W1 possibly zero, W2 possibly absent: n_w2 = 0), each with or without the
 * geometric stiffening (stiff = 1: the deformation-dependent inertia W1 [W2] and, when vk_a has
 * rows, the membrane strain of runtime/stiffening.py).
 */
#include <string.h>

#include "superelement.h"
#include "so3.h"

/* Work arrays of `ffrf_superelement` and its Jacobian: the same names and shapes as the numpy path's
 * (r: rows of vk_a, n2: n_w2). Bound once to a block that body.c allocates at creation. */
struct ffrf_se_work {
    int n, nb, nc, nv, r, n2;                   /* the sizes the arrays were laid out for */
    double *q, *qd, *g;                         /* [n]    q_bar (89), q_bar_dot (91), g (78) */
    double *rho, *Q, *H, *alpha;                /* [nb][3], [nb][3][3], [nb][3][3], [nb][3] */
    double *x0, *W0, *x0dot;                    /* [3] */
    double *v, *vdot;                           /* [nv] */
    double *u, *c;                              /* [nb][3] */
    double *v3, *v3b;                           /* [3] */
    double *GW;                                 /* [n][n]  G(W0) (53) */
    double *h, *torque;                         /* [3] */
    double *Gq, *Gqd, *Gr, *Grd, *dsdq;         /* [3][n] */
    double *fa;                                 /* [nb][3] */
    double *Dq, *Dqd;                           /* [n][nc] */
    double *dgz, *dgy;                          /* [n][nc + nv] */
    double *S, *S2, *B, *W0x, *C, *QC;          /* [3][3] */
    double *T1, *T2;                            /* [3][nc] */
    double *Bq;                                 /* [r][n] */
    double *Nk;                                 /* [r] */
    double *Z;                                  /* [3][n] */
    double *Jq, *Jqd;                           /* [3][3] */
    double *hs;                                 /* [3] */
    double *Kt;                                 /* [n][n] */
    double *eq;                                 /* [3][n] */
    double *V, *Vd;                             /* [n2][3][3] */
    double *Kc;                                 /* [n2][n2] */
    double *HQ;                                 /* [3][n] */
    double *MGW, *MGq;                          /* [n][n], [3][n]  M_bar^-1 G(W0), M_bar^-1 G_k q (the refresh's k_q rows) */
    int *nz, *nz_count;                         /* [nc][n], [nc]: the nonzero rows of each column of Dq, Dqd */
    int *cols;                                  /* [2][nc + nv]: Newton positions of the local columns that are unknowns, their local index */
    int *rows;                                  /* [2][nv + nc]: the same of the local rows */
};

#define SE_ALIGN 16 /* every array starts on a 16-byte boundary of the block */

static size_t se_round(size_t bytes) { return (bytes + SE_ALIGN - 1) / SE_ALIGN * SE_ALIGN; }

/* Walks the arrays of the work struct in one order, for both the size and the binding: with
 * w == NULL only the bytes are counted. */
static size_t se_layout(ffrf_se_work *w, char *mem, const ffrf_dims *d)
{
    size_t n = (size_t)d->n, nb = (size_t)d->nb, nc = (size_t)d->nc, nv = (size_t)d->nv;
    size_t r = (size_t)d->n_vk, n2 = (size_t)d->n_w2, ncv = nc + nv;
    size_t off = se_round(sizeof(struct ffrf_se_work));
#define SE_ARRAY(name, count)                                                  \
    do {                                                                       \
        if (w) w->name = (double *)(void *)(mem + off);                        \
        off += se_round((count) * sizeof(double));                             \
    } while (0)
    SE_ARRAY(q, n); SE_ARRAY(qd, n); SE_ARRAY(g, n);
    SE_ARRAY(rho, nb * 3); SE_ARRAY(Q, nb * 9); SE_ARRAY(H, nb * 9); SE_ARRAY(alpha, nb * 3);
    SE_ARRAY(x0, 3); SE_ARRAY(W0, 3); SE_ARRAY(x0dot, 3);
    SE_ARRAY(v, nv); SE_ARRAY(vdot, nv);
    SE_ARRAY(u, nb * 3); SE_ARRAY(c, nb * 3);
    SE_ARRAY(v3, 3); SE_ARRAY(v3b, 3);
    SE_ARRAY(GW, n * n);
    SE_ARRAY(h, 3); SE_ARRAY(torque, 3);
    SE_ARRAY(Gq, 3 * n); SE_ARRAY(Gqd, 3 * n); SE_ARRAY(Gr, 3 * n); SE_ARRAY(Grd, 3 * n); SE_ARRAY(dsdq, 3 * n);
    SE_ARRAY(fa, nb * 3);
    SE_ARRAY(Dq, n * nc); SE_ARRAY(Dqd, n * nc);
    SE_ARRAY(dgz, n * ncv); SE_ARRAY(dgy, n * ncv);
    SE_ARRAY(S, 9); SE_ARRAY(S2, 9); SE_ARRAY(B, 9); SE_ARRAY(W0x, 9); SE_ARRAY(C, 9); SE_ARRAY(QC, 9);
    SE_ARRAY(T1, 3 * nc); SE_ARRAY(T2, 3 * nc);
    SE_ARRAY(Bq, r * n); SE_ARRAY(Nk, r);
    SE_ARRAY(Z, 3 * n);
    SE_ARRAY(Jq, 9); SE_ARRAY(Jqd, 9); SE_ARRAY(hs, 3);
    SE_ARRAY(Kt, n * n);
    SE_ARRAY(eq, 3 * n);
    SE_ARRAY(V, n2 * 9); SE_ARRAY(Vd, n2 * 9); SE_ARRAY(Kc, n2 * n2);
    SE_ARRAY(HQ, 3 * n);
    SE_ARRAY(MGW, n * n); SE_ARRAY(MGq, 3 * n);
#undef SE_ARRAY
    if (w) w->nz = (int *)(void *)(mem + off);
    off += se_round(n * nc * sizeof(int));
    if (w) w->nz_count = (int *)(void *)(mem + off);
    off += se_round(nc * sizeof(int));
    if (w) w->cols = (int *)(void *)(mem + off);
    off += se_round(2 * ncv * sizeof(int));
    if (w) w->rows = (int *)(void *)(mem + off);
    off += se_round(2 * ncv * sizeof(int));
    if (w) {
        w->n = d->n; w->nb = d->nb; w->nc = d->nc; w->nv = d->nv; w->r = d->n_vk; w->n2 = d->n_w2;
    }
    return off;
}

size_t ffrf_se_work_bytes(const ffrf_dims *d) { return se_layout(NULL, NULL, d); }

/* The work struct at the start of `mem` and its arrays after it, all zero (the numpy path allocates them
 * with np.zeros: an array a term set never writes reads as zero). */
ffrf_se_work *ffrf_se_work_bind(void *mem, const ffrf_dims *d)
{
    size_t bytes = ffrf_se_work_bytes(d);
    ffrf_se_work *w = (ffrf_se_work *)mem;
    memset(mem, 0, bytes);
    se_layout(w, (char *)mem, d);
    return w;
}

static void skew(const double *a, double (*out)[3]) { ffrf_skew(a, &out[0][0]); }

/* out = A B, or A B^T when bt (3 x 3), each entry summed from 0.0 over m in order (the plain loops' bits) */
static void mul33(const double (*A)[3], const double (*B)[3], int bt, double (*out)[3])
{
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) {
            double s = 0.0;
            for (int m = 0; m < 3; m++)
                s += A[i][m] * (bt ? B[j][m] : B[m][j]);
            out[i][j] = s;
        }
}

/* X = sum_j q_j T_j and Y = sum_j qd_j T_j over the n 3 x 3 matrices T_j, each entry summed from 0.0 over j
 * in order (the plain loops' bits) */
static void weighted_sums(int n, const double *q, const double *qd, const double (*T)[3][3], double (*X)[3],
                          double (*Y)[3])
{
    for (int a = 0; a < 3; a++)
        for (int bb = 0; bb < 3; bb++) {
            double s1 = 0.0, s2 = 0.0;
            for (int j = 0; j < n; j++) {
                s1 += q[j] * T[j][a][bb];
                s2 += qd[j] * T[j][a][bb];
            }
            X[a][bb] = s1;
            Y[a][bb] = s2;
        }
}

/* g += f_vk(q) - f0(Omega0) [- Kc(Omega0) q] (stiffening.von_karman, deformed_inertia); keeps Bq,
 * N = a q + sigma, Z(Omega0) (Z[:, j] = W1_j Omega0) [and Kc] in w for the Jacobian and the rotation
 * rows. W2 absent: n_w2 = 0. */
static void stiff_force(const ffrf_body *b, int e, const double *q, const double *Om, double *g, ffrf_se_work *w)
{
    const int r = b->dims.n_vk, n = b->dims.n, n2 = b->dims.n_w2;
    const double (*vk_a)[n] = (const double (*)[n])b->data.vk_a + (size_t)e * r;
    const double (*vk_B)[n][n] = (const double (*)[n][n])b->data.vk_B + (size_t)e * r;
    const double (*W1)[3][3] = (const double (*)[3][3])b->data.W1 + (size_t)e * b->dims.n_w1;
    double (*Bq)[n] = (double (*)[n])w->Bq, *Nk = w->Nk;
    double (*Z)[n] = (double (*)[n])w->Z;
    for (int k = 0; k < r; k++) {
        double ek = 0.0, sk = 0.0;
        for (int i = 0; i < n; i++) {
            double s = 0.0;
            for (int j = 0; j < n; j++)
                s += vk_B[k][i][j] * q[j];
            Bq[k][i] = s;
            ek += vk_a[k][i] * q[i];
        }
        for (int i = 0; i < n; i++)
            sk += 0.5 * Bq[k][i] * q[i];
        Nk[k] = ek + sk;
        for (int i = 0; i < n; i++) /* a^T sigma + Bq^T N */
            g[i] += vk_a[k][i] * sk + Bq[k][i] * Nk[k];
    }
    for (int j = 0; j < n; j++) {
        double s = 0.0;
        for (int a = 0; a < 3; a++) {
            double za = 0.0;
            for (int bb = 0; bb < 3; bb++)
                za += W1[j][a][bb] * Om[bb];
            Z[a][j] = za;
            s += za * Om[a];
        }
        g[j] -= 0.5 * s;
    }
    if (n2 > 0) { /* the elastic centrifugal force -Kc(Omega0) q, Kc_jl = Omega0^T W2_jl Omega0 */
        const double (*W2)[n2][3][3] = (const double (*)[n2][3][3])b->data.W2 + (size_t)e * n2;
        double (*Kc)[n2] = (double (*)[n2])w->Kc;
        for (int j = 0; j < n; j++) {
            double s = 0.0;
            for (int l = 0; l < n; l++) {
                double kc = 0.0;
                for (int a = 0; a < 3; a++)
                    for (int bb = 0; bb < 3; bb++)
                        kc += Om[a] * W2[j][l][a][bb] * Om[bb];
                Kc[j][l] = kc;
                s += kc * q[l];
            }
            g[j] -= s;
        }
    }
}

/* Kt = a^T Bq + Bq^T a + Bq^T Bq + sum_k N_k B_k (stiffening.von_karman) into w->Kt. */
static void stiff_tangent(const ffrf_body *b, int e, int n, ffrf_se_work *w)
{
    const int r = b->dims.n_vk;
    const double (*vk_a)[n] = (const double (*)[n])b->data.vk_a + (size_t)e * r;
    const double (*vk_B)[n][n] = (const double (*)[n][n])b->data.vk_B + (size_t)e * r;
    const double (*Bq)[n] = (const double (*)[n])w->Bq, *Nk = w->Nk;
    double (*Kt)[n] = (double (*)[n])w->Kt;
    /* k outermost: each entry sums its terms in k's order from 0.0 as a k-innermost loop would, the rows of
     * vk_B[k] read contiguously. Kt is symmetric (each B_k is: runtime/stiffening.py): the upper triangle is
     * summed, the lower one copied from it. */
    for (int i = 0; i < n; i++)
        for (int j = i; j < n; j++)
            Kt[i][j] = 0.0;
    for (int k = 0; k < r; k++)
        for (int i = 0; i < n; i++) {
            const double ai = vk_a[k][i], bi = Bq[k][i], *a = vk_a[k], *bq = Bq[k], *Bki = vk_B[k][i];
            for (int j = i; j < n; j++)
                Kt[i][j] += ai * bq[j] + bi * (a[j] + bq[j]) + Nk[k] * Bki[j];
        }
    for (int i = 1; i < n; i++)
        for (int j = 0; j < i; j++)
            Kt[i][j] = Kt[j][i];
}

/* C[i][0..2] += A[i][0..2] B [+ A2[i][0..2] B2] (i < n; A, A2 n x 3, B, B2 3 x 3, C n x 3 within matrices of
 * leading sizes lda, ldb, ldc), each entry's sum in m's order from C's value (with A2: the pairs
 * A[i][m] B[m][j] + A2[i][m] B2[m][j] summed). */
static void block_product(int n, const double *A, const double *A2, int lda, const double *B, const double *B2,
                          int ldb, double *C, int ldc)
{
    const double b00 = B[0], b01 = B[1], b02 = B[2];
    const double b10 = B[ldb], b11 = B[ldb + 1], b12 = B[ldb + 2];
    const double b20 = B[2 * ldb], b21 = B[2 * ldb + 1], b22 = B[2 * ldb + 2];
    if (!A2) {
        for (int i = 0; i < n; i++, A += lda, C += ldc) {
            const double a0 = A[0], a1 = A[1], a2 = A[2];
            C[0] = ((C[0] + a0 * b00) + a1 * b10) + a2 * b20;
            C[1] = ((C[1] + a0 * b01) + a1 * b11) + a2 * b21;
            C[2] = ((C[2] + a0 * b02) + a1 * b12) + a2 * b22;
        }
        return;
    }
    const double c00 = B2[0], c01 = B2[1], c02 = B2[2];
    const double c10 = B2[ldb], c11 = B2[ldb + 1], c12 = B2[ldb + 2];
    const double c20 = B2[2 * ldb], c21 = B2[2 * ldb + 1], c22 = B2[2 * ldb + 2];
    for (int i = 0; i < n; i++, A += lda, A2 += lda, C += ldc) {
        const double a0 = A[0], a1 = A[1], a2 = A[2], e0 = A2[0], e1 = A2[1], e2 = A2[2];
        C[0] = ((C[0] + (a0 * b00 + e0 * c00)) + (a1 * b10 + e1 * c10)) + (a2 * b20 + e2 * c20);
        C[1] = ((C[1] + (a0 * b01 + e0 * c01)) + (a1 * b11 + e1 * c11)) + (a2 * b21 + e2 * c21);
        C[2] = ((C[2] + (a0 * b02 + e0 * c02)) + (a1 * b12 + e1 * c12)) + (a2 * b22 + e2 * c22);
    }
}

/* C [rows][nc] (leading size ldc) += A Dq [+ A2 Dqd] (A, A2 [rows][n], leading size lda; Dq, Dqd [n][nc]) by Dq's
 * blocks, whose pattern is the same at every state (jacobian below; Dqd's nonzeros lie in them too): per node
 * -R0^T (x0) and skew(rho) (Theta0) on its translation rows, -H Q^T (Theta0) on its rotation rows, R0^T and H on
 * its own columns, and 1 on each modal row. Each sum runs over the rows of the column's nonzero list in their
 * order; the structural zeros beside them add nothing, so the sums are those of the list's loop to the bit.
 * solved: the columns that are not Newton unknowns are left alone (as with the lists: not read). */
static void dq_product(const ffrf_body *b, int e, int solved, int rows, const double *A, const double *A2, int lda,
                       const double *Dq, const double *Dqd, double *C, int ldc)
{
    const int nb = b->dims.nb, nm = b->dims.nm, nc = b->dims.nc;
    const idx_t *cfg = b->data.cfg_map + (size_t)e * nc, *pos = b->data.newton_pos;
#define UNKNOWN(j) (!solved || pos[cfg[j]] < b->dims.nf)
    for (int k = 0; k < nb; k++) {
        const int d = 6 * k, a = d + 3, XP = 6 + nm + d;
        const int blk[5][2] = {{d, 0}, {d, 3}, {a, 3}, {d, XP}, {a, XP + 3}}; /* (first row, first column) */
        for (int t = 0; t < 5; t++) {
            const size_t m0 = (size_t)blk[t][0], j0 = (size_t)blk[t][1];
            if (UNKNOWN(j0))
                block_product(rows, A + m0, A2 ? A2 + m0 : NULL, lda, Dq + m0 * nc + j0, Dqd + m0 * nc + j0, nc, C + j0, ldc);
        }
    }
    for (int l = 0; l < nm; l++) {
        const size_t m = (size_t)(6 * nb + l), j = (size_t)(6 + l);
        if (UNKNOWN(j))
            for (int i = 0; i < rows; i++) {
                double *c = C + (size_t)i * ldc + j;
                const double *ai = A + (size_t)i * lda + m;
                *c = A2 ? *c + (ai[0] * Dq[m * nc + j] + A2[(size_t)i * lda + m] * Dqd[m * nc + j]) : *c + ai[0] * Dq[m * nc + j];
            }
    }
#undef UNKNOWN
}

/* The local Jacobian blocks of `ffrf_superelement`: Fz = F_ydot, Fy = F_y [nv + nc][nc + nv]
 * (runtime/equations.py residual_and_jacobian, same algebra). solved (a refresh, ffrf_evaluate): the k_q rows
 * (79) premultiplied by M_bar^-1, as factor.c's velocity elimination wants them: M_bar^-1 k_q's blocks are
 * Dq [+ M_bar^-1 G_k q on W0] (F_ydot) and Dqd [+ M_bar^-1 G(W0) Dq] and -I on r (F_y), M_bar^-1 G_k made at
 * creation (work.MG): the products with M_bar and M_bar^-1 are not formed. */
static void jacobian(const ffrf_body *b, int e, const double (*R0)[3], ffrf_se_work *w, int solved, double *Fz_,
                     double *Fy_)
{
    const int gyro = b->data.gyro, stiff = b->data.stiff;
    const int nb = b->dims.nb, nm = b->dims.nm, n = b->dims.n, nc = b->dims.nc, nv = b->dims.nv;
    const int ncv = nc + nv, ng = b->dims.n_g, n2 = b->dims.n_w2;
    const double (*Ke)[n] = (const double (*)[n])b->data.K + (size_t)e * n;
    const double (*Me)[n] = (const double (*)[n])b->data.M + (size_t)e * n;
    const int damped = b->damping.on; /* structural damping D q_bar_dot in g (runtime/damping.py) */
    const double (*De)[n] = (const double (*)[n])b->damping.D + (size_t)(damped ? e : 0) * n;
    const double (*Je)[3] = (const double (*)[3])b->data.J0 + (size_t)e * 3;
    const double (*G)[ng][ng] = (const double (*)[ng][ng])b->data.G + (size_t)e * 3;
    const double *mass = b->data.mass;
    const double *g = w->g, *h = w->h, *W0 = w->W0;
    const double *r = w->v + 6, *rdot = w->vdot + 6;
    double (*rho)[3] = (double (*)[3])w->rho, (*alpha)[3] = (double (*)[3])w->alpha;
    double (*Q)[3][3] = (double (*)[3][3])w->Q, (*H)[3][3] = (double (*)[3][3])w->H;
    double (*Dq)[nc] = (double (*)[nc])w->Dq, (*Dqd)[nc] = (double (*)[nc])w->Dqd;
    double (*dgz)[ncv] = (double (*)[ncv])w->dgz, (*dgy)[ncv] = (double (*)[ncv])w->dgy;
    double (*S)[3] = (double (*)[3])w->S, (*S2)[3] = (double (*)[3])w->S2, (*B)[3] = (double (*)[3])w->B;
    double (*W0x)[3] = (double (*)[3])w->W0x;
    double (*u)[3] = (double (*)[3])w->u, (*cc)[3] = (double (*)[3])w->c;
    double (*Fz)[ncv] = (double (*)[ncv])Fz_, (*Fy)[ncv] = (double (*)[ncv])Fy_;
    /* The blocks' zeros. Dq, Dqd, dgz, dgy: every entry this function writes it sets (=) before it adds
     * into it, on the same pattern at every call (the term set is the body's), and the others stay the zeros
     * of ffrf_se_work_bind. Fz, Fy: the caller's arrays are zeroed whole; the body's own (work.Fz, work.Fy, a
     * refresh's: kept by the runtime alone, zero at creation) only on the rows that are added into, x0, Theta0
     * and the boundary nodes' (nv .. nv + 6, nv + 6 + nm .. nv + nc): the other rows' entries are set at every
     * call or never written (ffrf_evaluate's tangent products overwrite only entries that are set here). */
    const size_t row_bytes = sizeof(double) * (size_t)ncv;
    if (Fz_ == b->work.Fz && Fy_ == b->work.Fy) {
        memset(Fz[nv], 0, 6 * row_bytes);
        memset(Fy[nv], 0, 6 * row_bytes);
        memset(Fz[nv + 6 + nm], 0, (size_t)(nc - 6 - nm) * row_bytes);
        memset(Fy[nv + 6 + nm], 0, (size_t)(nc - 6 - nm) * row_bytes);
    } else {
        memset(Fz_, 0, (size_t)(nv + nc) * row_bytes);
        memset(Fy_, 0, (size_t)(nv + nc) * row_bytes);
    }
    skew(W0, W0x);
    for (int k = 0; k < nb; k++) {
        const int XP = 6 + nm + 6 * k, TP = 9 + nm + 6 * k;
        const int d = 6 * k, a = 6 * k + 3;
        skew(rho[k], S);
        double HQ[3][3];
        mul33((const double (*)[3])H[k], (const double (*)[3])Q[k], 1, HQ);
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < 3; j++) {
                Dq[d + i][j] = -R0[j][i]; /* d d_P = -R0^T dx0 + skew(rho) dTheta0 + R0^T dx_P */
                Dq[d + i][3 + j] = S[i][j];
                Dq[d + i][XP + j] = R0[j][i];
                Dq[a + i][TP + j] = H[k][i][j]; /* d alpha_P = H (dTheta_P - Q^T dTheta0) */
                Dq[a + i][3 + j] = -HQ[i][j];
            }
        /* d(d_Pdot) = skew(u) dTheta0 - skew(W0) d(d_P) */
        skew(u[k], S);
        for (int i = 0; i < 3; i++) { /* (on Dq's nonzero columns of these rows, x0, Theta0 and the node's x_P: the others stay 0) */
            for (int t = 0; t < 9; t++) {
                const int j = t < 6 ? t : XP + t - 6;
                double s = 0.0;
                for (int m = 0; m < 3; m++)
                    s -= W0x[i][m] * Dq[d + m][j];
                Dqd[d + i][j] = s;
            }
            for (int j = 0; j < 3; j++)
                Dqd[d + i][3 + j] += S[i][j];
        }
        /* d(H c) = B eps, B = -c alpha^T - skew(Q^T c)/2 - H skew(Q^T W0) */
        const double *c = cc[k];
        double *QTc = w->v3, *QTW = w->v3b;
        for (int i = 0; i < 3; i++) {
            double s1 = 0.0, s2 = 0.0;
            for (int j = 0; j < 3; j++) {
                s1 += Q[k][j][i] * c[j];
                s2 += Q[k][j][i] * W0[j];
            }
            QTc[i] = s1;
            QTW[i] = s2;
        }
        skew(QTc, S);
        skew(QTW, S2);
        double HS2[3][3], BQ[3][3];
        mul33((const double (*)[3])H[k], (const double (*)[3])S2, 0, HS2);
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < 3; j++)
                B[i][j] = -c[i] * alpha[k][j] - 0.5 * S[i][j] - HS2[i][j];
        mul33((const double (*)[3])B, (const double (*)[3])Q[k], 1, BQ);
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < 3; j++) {
                Dqd[a + i][TP + j] = B[i][j];
                Dqd[a + i][3 + j] = -BQ[i][j];
            }
    }
    for (int i = 0; i < nm; i++)
        Dq[6 * nb + i][6 + i] = 1.0;
    /* The nonzero rows of each column of Dq and Dqd: both are sparse (a boundary row holds the CM
     * frame's and its node's columns, a modal row one), and the products with them below run over these
     * rows only. They skip exact zeros, so every sum is the full loop's to the bit. solved (a refresh): a column
     * that is not a Newton unknown (a motion-driven node's) gets none, its products are never read. */
    int *nzm = w->nz, *nzc = w->nz_count;
    const idx_t *cfg = b->data.cfg_map + (size_t)e * nc, *newton_pos = b->data.newton_pos;
    const int lists = !solved || damped || gyro; /* (the products that run over them: the others go by Dq's blocks) */
    for (int j = 0; j < (lists ? nc : 0); j++) {
        int cnt = 0;
        for (int m = 0; m < (solved && newton_pos[cfg[j]] >= b->dims.nf ? 0 : n); m++)
            if (Dq[m][j] != 0.0 || Dqd[m][j] != 0.0)
                nzm[(size_t)j * n + cnt++] = m;
        nzc[j] = cnt;
    }
#define NZ_ROWS(j, m) for (int t_ = 0, m = 0; t_ < nzc[j] && (m = nzm[(size_t)(j) * n + t_], 1); t_++)
    const int cv0 = nc, cO0 = nc + 3, cr = nc + 6;
    const int kq = 6, ex0 = nv, eT0 = nv + 3, eeta = nv + 6;
    for (int i = 0; i < 3; i++) {
        Fz[i][i] = 1.0; /* x0dot - v0 */
        Fy[i][cv0 + i] = -1.0;
        Fz[3 + i][3 + i] = 1.0; /* W0 - Omega0 */
        Fy[3 + i][cO0 + i] = -1.0;
        Fz[ex0 + i][cv0 + i] = mass[e];
    }
    /* The stiffness that multiplies Dq in dg/d(configuration): K, or with the stiffening K + Kt [- Kc]
     * (d(f_vk - f0 [- Kc q])/dq), summed first so that Dq's product is taken once */
    const double (*Kq)[n] = Ke;
    if (stiff) {
        double (*Kt)[n] = (double (*)[n])w->Kt;
        stiff_tangent(b, e, n, w);
        const double (*Kc)[n2 > 0 ? n2 : 1] = (const double (*)[n2 > 0 ? n2 : 1])w->Kc;
        for (int i = 0; i < n; i++) /* (Kt - Kc) + K, one pass */
            for (int j = 0; j < n; j++)
                Kt[i][j] = (n2 > 0 ? Kt[i][j] - Kc[i][j] : Kt[i][j]) + Ke[i][j];
        Kq = (const double (*)[n])Kt;
    }
    /* Kq Dq into dgy's configuration columns, by Dq's blocks */
    for (int i = 0; i < n; i++)
        for (int j = 0; j < nc; j++)
            dgy[i][j] = 0.0;
    dq_product(b, e, solved, n, &Kq[0][0], NULL, n, &Dq[0][0], &Dqd[0][0], &dgy[0][0], ncv);
    for (int i = 0; i < n; i++) { /* k_q = M (qdot - r) [+ G(W0) q]; g = K q + M rdot [+ G(W0) r] [+ D qdot] */
        double *fz = Fz[kq + i], *fy = Fy[kq + i];
        if (solved) /* M_bar^-1 k_q: Dq, Dqd and -I on r */
            for (int j = 0; j < nc; j++) {
                fz[j] = Dq[i][j];
                fy[j] = Dqd[i][j];
            }
        else
            for (int j = 0; j < nc; j++) {
                double s1 = 0.0, s2 = 0.0;
                NZ_ROWS(j, m) {
                    s1 += Me[i][m] * Dq[m][j];
                    s2 += Me[i][m] * Dqd[m][j];
                }
                fz[j] = s1;
                fy[j] = s2;
            }
        for (int j = 0; j < nc; j++) { /* d(D qdot) = D Dq d(rates) + D Dqd d(configuration): qdot of (91) depends on both */
            double s4 = 0.0, s5 = 0.0;
            if (damped) {
                NZ_ROWS(j, m) {
                    s4 += De[i][m] * Dq[m][j];
                    s5 += De[i][m] * Dqd[m][j];
                }
                dgy[i][j] += s5; /* Kq Dq + D Dqd (undamped: + 0, nothing) */
            }
            dgz[i][j] = s4;
        }
        for (int j = nc; j < ncv; j++) /* (dgy's velocity columns are added into below: the gyroscopic and stiffening terms) */
            dgy[i][j] = 0.0;
        for (int j = 0; j < n; j++) {
            fy[cr + j] = solved ? (i == j ? -1.0 : 0.0) : -Me[i][j];
            dgz[i][cr + j] = Me[i][j];
        }
    }
    /* angular momentum rows: J0 Omega0dot + W0 x h */
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) {
            Fz[eT0 + i][cO0 + j] = Je[i][j];
            double s = 0.0;
            for (int m = 0; m < 3; m++)
                s += W0x[i][m] * Je[m][j];
            Fy[eT0 + i][cO0 + j] = s;
        }
    skew(h, S); /* h includes s for the gyroscopic set */
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            Fz[eT0 + i][3 + j] -= S[i][j];
    if (gyro) {
        double (*GW)[n] = (double (*)[n])w->GW;
        double (*Gr)[n] = (double (*)[n])w->Gr, (*Grd)[n] = (double (*)[n])w->Grd;
        double (*dsdq)[n] = (double (*)[n])w->dsdq;
        for (int kk = 0; kk < 3; kk++)
            for (int i = 0; i < n; i++) {
                double s1 = 0.0, s2 = 0.0, s3 = 0.0;
                for (int j = 0; j < n; j++) {
                    s1 += G[kk][i][j] * r[j];
                    s2 += r[j] * G[kk][j][i];    /* (r^T G_k)_i */
                    s3 += rdot[j] * G[kk][j][i]; /* (rdot^T G_k)_i */
                }
                Gr[kk][i] = s1;
                dsdq[kk][i] = s2;
                Grd[kk][i] = s3;
            }
        /* the k_q rows' G(W0) q: G(W0) and G_k q, or with solved M_bar^-1 G(W0) and M_bar^-1 G_k q */
        const double (*KW)[n] = (const double (*)[n])GW, (*KWq)[n] = (const double (*)[n])w->Gq;
        if (solved && (gyro & FFRF_CORIOLIS)) {
            const double (*MG)[n][n] = (const double (*)[n][n])b->work.MG + (size_t)e * 3;
            double (*MGW)[n] = (double (*)[n])w->MGW, (*MGq)[n] = (double (*)[n])w->MGq;
            const double *q = w->q;
            for (int i = 0; i < n; i++)
                for (int j = 0; j < n; j++)
                    MGW[i][j] = W0[0] * MG[0][i][j] + W0[1] * MG[1][i][j] + W0[2] * MG[2][i][j];
            for (int kk = 0; kk < 3; kk++)
                for (int i = 0; i < n; i++) {
                    double s = 0.0;
                    for (int j = 0; j < n; j++)
                        s += MG[kk][i][j] * q[j];
                    MGq[kk][i] = s;
                }
            KW = (const double (*)[n])MGW;
            KWq = (const double (*)[n])MGq;
        }
        for (int i = 0; i < ((gyro & FFRF_CORIOLIS) ? n : 0); i++) {
            for (int kk = 0; kk < 3; kk++) {
                Fz[kq + i][3 + kk] += KWq[kk][i]; /* d(G(W0) q)/dW0 */
                dgz[i][3 + kk] += Gr[kk][i];
            }
            for (int j = 0; j < nc; j++) {
                double s = 0.0;
                NZ_ROWS(j, m)
                    s += KW[i][m] * Dq[m][j];
                Fy[kq + i][j] += s;
            }
            for (int j = 0; j < n; j++)
                dgy[i][cr + j] += GW[i][j];
        }
    }
    if (gyro & FFRF_COUPLING) { /* s and sdot: rows of ds/dq, ds/dr, dsdot/d... */
        const double (*Gq)[n] = (const double (*)[n])w->Gq, (*Gqd)[n] = (const double (*)[n])w->Gqd;
        const double (*Grd)[n] = (const double (*)[n])w->Grd, (*dsdq)[n] = (const double (*)[n])w->dsdq;
        double (*T1)[nc] = (double (*)[nc])w->T1; /* (3, nc): ds_dq Dq ; T2 = rdot^T G_k Dq ; T3 = ds_dq Dqd */
        for (int kk = 0; kk < 3; kk++) {
            for (int j = 0; j < nc; j++) {
                double s1 = 0.0, s2 = 0.0, s3 = 0.0;
                NZ_ROWS(j, m) {
                    s1 += dsdq[kk][m] * Dq[m][j];
                    s2 += Grd[kk][m] * Dq[m][j];
                    s3 += dsdq[kk][m] * Dqd[m][j];
                }
                T1[kk][j] = s1;
                Fy[eT0 + kk][j] += s2 + s3;
                Fz[eT0 + kk][j] += s1;
            }
            for (int j = 0; j < n; j++) {
                Fz[eT0 + kk][cr + j] += Gq[kk][j];
                Fy[eT0 + kk][cr + j] += Gqd[kk][j];
            }
        }
        for (int i = 0; i < 3; i++) {
            for (int j = 0; j < nc; j++) {
                double s = 0.0;
                for (int m = 0; m < 3; m++)
                    s += W0x[i][m] * T1[m][j];
                Fy[eT0 + i][j] += s;
            }
            for (int j = 0; j < n; j++) {
                double s = 0.0;
                for (int m = 0; m < 3; m++)
                    s += W0x[i][m] * Gq[m][j];
                Fy[eT0 + i][cr + j] += s;
            }
        }
    }
    if (stiff) { /* d(f_vk - f0 [- Kc q]) on the Omega0 columns: -HQ^T (the configuration's part is Kq's above) */
        const double (*HQ)[n] = (const double (*)[n])w->HQ;
        for (int i = 0; i < n; i++)
            for (int bb = 0; bb < 3; bb++)
                dgy[i][cO0 + bb] -= HQ[bb][i];
    }
    for (int i = 0; i < nm; i++)
        for (int j = 0; j < ncv; j++) {
            Fz[eeta + i][j] = dgz[6 * nb + i][j];
            Fy[eeta + i][j] = dgy[6 * nb + i][j];
        }
    /* g_B through (91): equations.project_boundary_force */
    double (*C)[3] = (double (*)[3])w->C, (*QC)[3] = (double (*)[3])w->QC;
    double (*fa)[3] = (double (*)[3])w->fa;
    for (int k = 0; k < nb; k++) {
        const int exP = nv + 6 + nm + 6 * k, eTP = nv + 9 + nm + 6 * k;
        const int TP = 9 + nm + 6 * k;
        const int d = 6 * k, a = 6 * k + 3;
        const double *gd = g + d, *ga = g + a;
        /* R0, H, Q and rho in locals: the stores into the blocks below cannot change them (no reloads) */
        double r0[9], hk[9], qk[9], rk[3];
        for (int i = 0; i < 3; i++) {
            rk[i] = rho[k][i];
            for (int m = 0; m < 3; m++) {
                r0[3 * i + m] = R0[i][m];
                hk[3 * i + m] = H[k][i][m];
                qk[3 * i + m] = Q[k][i][m];
            }
        }
        for (int pass = 0; pass < 2; pass++) { /* (Fz, dgz), then (Fy, dgy): -(rho x dg_d + Q H^T dg_a) on Theta0 */
            double (*D)[ncv] = pass == 0 ? Fz : Fy;
            double (*dg)[ncv] = pass == 0 ? dgz : dgy;
            /* the columns where this node's rows of dg are not all zero (dgz: the r columns, without damping or
             * gyroscopic terms; dgy: the configuration columns, r and Omega0 with those terms): a zero column adds
             * nothing, so the others' sums are those of the full loop */
            int *cols = w->cols, ncols = 0;
            for (int j = 0; j < ncv; j++)
                if (dg[d][j] != 0.0 || dg[d + 1][j] != 0.0 || dg[d + 2][j] != 0.0 || dg[a][j] != 0.0 ||
                    dg[a + 1][j] != 0.0 || dg[a + 2][j] != 0.0)
                    cols[ncols++] = j;
            for (int t = 0; t < ncols; t++) {
                const int j = cols[t];
                const double gdj[3] = {dg[d][j], dg[d + 1][j], dg[d + 2][j]}, gaj[3] = {dg[a][j], dg[a + 1][j], dg[a + 2][j]};
                double s1[3], ya[3];
                for (int i = 0; i < 3; i++) { /* R0 dg_d, H^T dg_a */
                    s1[i] = ((0.0 + r0[3 * i] * gdj[0]) + r0[3 * i + 1] * gdj[1]) + r0[3 * i + 2] * gdj[2];
                    ya[i] = ((0.0 + hk[i] * gaj[0]) + hk[3 + i] * gaj[1]) + hk[6 + i] * gaj[2];
                }
                const double rx[3] = {rk[1] * gdj[2] - rk[2] * gdj[1], rk[2] * gdj[0] - rk[0] * gdj[2],
                                      rk[0] * gdj[1] - rk[1] * gdj[0]}; /* rho x dg_d */
                for (int i = 0; i < 3; i++) {
                    D[exP + i][j] += s1[i];
                    D[ex0 + i][j] -= s1[i];
                    D[eTP + i][j] += ya[i];
                    D[eT0 + i][j] -= ((rx[i] + qk[3 * i] * ya[0]) + qk[3 * i + 1] * ya[1]) + qk[3 * i + 2] * ya[2];
                }
            }
        }
        skew(gd, S);
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < 3; j++) {
                double s = 0.0;
                for (int m = 0; m < 3; m++)
                    s += R0[i][m] * S[m][j];
                Fy[exP + i][3 + j] -= s; /* d(R0 g_d) = -R0 skew(g_d) dTheta0 + ... */
                Fy[ex0 + i][3 + j] += s;
            }
        /* C = -g_a alpha^T + Q skew(g_a)/2 on the node rotation rows */
        skew(ga, S2);
        double QS2[3][3], CQ[3][3];
        mul33((const double (*)[3])Q[k], (const double (*)[3])S2, 0, QS2);
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < 3; j++)
                C[i][j] = -ga[i] * alpha[k][j] + 0.5 * QS2[i][j];
        mul33((const double (*)[3])C, (const double (*)[3])Q[k], 1, CQ);
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < 3; j++) {
                Fy[eTP + i][TP + j] += C[i][j];
                Fy[eTP + i][3 + j] -= CQ[i][j];
            }
        /* CM rotation rows: + skew(g_d) Dq_d, and -Q (C - skew(f_a)) eps */
        for (int i = 0; i < 3; i++) /* (Dq_d's nonzero columns: x0, Theta0, the node's x_P) */
            for (int t = 0; t < 9; t++) {
                const int j = t < 6 ? t : 6 + nm + d + t - 6;
                double s = 0.0;
                for (int m = 0; m < 3; m++)
                    s += S[i][m] * Dq[d + m][j];
                Fy[eT0 + i][j] += s;
            }
        skew(fa[k], S2);
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < 3; j++) {
                double s = 0.0;
                for (int m = 0; m < 3; m++)
                    s += Q[k][i][m] * (C[m][j] - S2[m][j]);
                QC[i][j] = s;
            }
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < 3; j++) {
                Fy[eT0 + i][TP + j] -= QC[i][j];
                double s = 0.0;
                for (int m = 0; m < 3; m++)
                    s += QC[i][m] * Q[k][j][m];
                Fy[eT0 + i][3 + j] += s;
            }
    }
    if (stiff) { /* stiffening.rotation_rows derivatives */
        /* Z here is w->HQ, dh/dq = de/dqdot (stiffening.py deformed_inertia: h_q = e_qd) */
        const double (*Z)[n] = (const double (*)[n])w->HQ;
        const double (*Jq)[3] = (const double (*)[3])w->Jq, (*Jqd)[3] = (const double (*)[3])w->Jqd;
        double (*eq)[n] = (double (*)[n])w->eq;
        const double *Om = w->v + 3, *Omd = w->vdot + 3;
        const double (*W1)[3][3] = (const double (*)[3][3])b->data.W1 + (size_t)e * b->dims.n_w1;
        const double (*V)[3][3] = (const double (*)[3][3])w->V, (*Vd)[3][3] = (const double (*)[3][3])w->Vd;
        for (int a = 0; a < 3; a++)
            for (int j = 0; j < n; j++) {
                double s = 0.0;
                for (int bb = 0; bb < 3; bb++) {
                    s += W1[j][a][bb] * Omd[bb];
                    if (n2 > 0)
                        s += V[j][a][bb] * Omd[bb] + Vd[j][a][bb] * Om[bb];
                }
                for (int bb = 0; bb < 3; bb++)
                    s += W0x[a][bb] * Z[bb][j];
                eq[a][j] = s; /* de/dq + W0 x dh/dq: de/dq = W1_j Omd [+ V_j Omd + Vd_j Om] */
            }
        skew(w->hs, S);
        for (int i = 0; i < 3; i++) {
            for (int j = 0; j < 3; j++) {
                Fz[eT0 + i][3 + j] -= S[i][j];    /* d(W0 x h)/dW0 */
                Fz[eT0 + i][cO0 + j] += Jq[i][j]; /* d/dOmega0dot */
                double s = Jqd[i][j];
                for (int m = 0; m < 3; m++)
                    s += W0x[i][m] * Jq[m][j];
                Fy[eT0 + i][cO0 + j] += s; /* W0 x (W1 q) + W1 qdot on Omega0 */
            }
        }
        /* Z Dq on F_ydot, eq Dq + Z Dqd on F_y (sums from 0, then added: as over the nonzero lists) */
        double (*Tz)[nc] = (double (*)[nc])w->T1, (*Ty)[nc] = (double (*)[nc])w->T2;
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < nc; j++)
                Tz[i][j] = Ty[i][j] = 0.0;
        dq_product(b, e, solved, 3, &Z[0][0], NULL, n, &Dq[0][0], &Dqd[0][0], &Tz[0][0], nc);
        dq_product(b, e, solved, 3, &eq[0][0], &Z[0][0], n, &Dq[0][0], &Dqd[0][0], &Ty[0][0], nc);
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < nc; j++) {
                Fz[eT0 + i][j] += Tz[i][j];
                Fy[eT0 + i][j] += Ty[i][j];
            }
    }
#undef NZ_ROWS
}

void ffrf_superelement(const ffrf_body *b, int e, const double *p, const double *yd, const double *R_,
                       int jac, double *F, double *Fz, double *Fy, ffrf_se_work *w)
{
    const int N = b->dims.N, gyro = b->data.gyro, stiff = b->data.stiff;
    const int n = b->dims.n, nb = b->dims.nb, nc = b->dims.nc, nv = b->dims.nv;
    const int nm = n - 6 * nb, ng = b->dims.n_g, n2 = b->dims.n_w2;
    const idx_t *cfg = b->data.cfg_map + (size_t)e * nc, *vel = b->data.vel_map + (size_t)e * nv;
    const idx_t *nodes = b->data.se_nodes + (size_t)e * nb;
    const double (*X_B)[3] = (const double (*)[3])b->data.X_B + (size_t)e * nb;
    const double (*Ke)[n] = (const double (*)[n])b->data.K + (size_t)e * n;
    const double (*Me)[n] = (const double (*)[n])b->data.M + (size_t)e * n;
    const int damped = b->damping.on;
    const double (*De)[n] = (const double (*)[n])b->damping.D + (size_t)(damped ? e : 0) * n;
    const double (*Je)[3] = (const double (*)[3])b->data.J0 + (size_t)e * 3;
    const double (*G)[ng][ng] = (const double (*)[ng][ng])b->data.G + (size_t)e * 3;
    const double *mass = b->data.mass, *gravity = b->data.gravity;
    const double (*R)[3][3] = (const double (*)[3][3])R_;
    double *q = w->q, *qd = w->qd, *g = w->g;
    double (*rho)[3] = (double (*)[3])w->rho, (*alpha)[3] = (double (*)[3])w->alpha;
    double (*Q)[3][3] = (double (*)[3][3])w->Q, (*H)[3][3] = (double (*)[3][3])w->H;
    double (*u)[3] = (double (*)[3])w->u, (*cc)[3] = (double (*)[3])w->c, (*fa)[3] = (double (*)[3])w->fa;
    const double (*R0)[3] = R[N + e];
    double *x0 = w->x0, *W0 = w->W0, *x0dot = w->x0dot;
    for (int i = 0; i < 3; i++) {
        x0[i] = p[cfg[i]];
        x0dot[i] = yd[cfg[i]];
        W0[i] = yd[cfg[3 + i]];
    }
    double *v = w->v, *vdot = w->vdot;
    for (int i = 0; i < nv; i++) {
        v[i] = p[vel[i]];
        vdot[i] = yd[vel[i]];
    }
    /* ---- boundary coordinates (89) and their rates (91), node by node */
    for (int k = 0; k < nb; k++) {
        const idx_t P = nodes[k];
        const int base = 6 + nm + 6 * k;
        for (int i = 0; i < 3; i++) {
            double s1 = 0.0, s2 = 0.0;
            for (int j = 0; j < 3; j++) {
                s1 += R0[j][i] * (p[cfg[base + j]] - x0[j]);
                s2 += R0[j][i] * (yd[cfg[base + j]] - x0dot[j]);
            }
            rho[k][i] = s1;
            u[k][i] = s2;
            for (int j = 0; j < 3; j++) {
                double s = 0.0;
                for (int m = 0; m < 3; m++)
                    s += R0[m][i] * R[P][m][j];
                Q[k][i][j] = s;
            }
        }
        alpha[k][0] = 0.5 * (Q[k][2][1] - Q[k][1][2]);
        alpha[k][1] = 0.5 * (Q[k][0][2] - Q[k][2][0]);
        alpha[k][2] = 0.5 * (Q[k][1][0] - Q[k][0][1]);
        const double tr = Q[k][0][0] + Q[k][1][1] + Q[k][2][2];
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < 3; j++)
                H[k][i][j] = 0.5 * ((i == j ? tr : 0.0) - Q[k][j][i]);
        double *c = cc[k];
        for (int i = 0; i < 3; i++) {
            double s = 0.0;
            for (int j = 0; j < 3; j++)
                s += Q[k][j][i] * W0[j];
            c[i] = yd[cfg[base + 3 + i]] - s;
        }
        double *rxW = w->v3;
        ffrf_cross(rho[k], W0, rxW);
        for (int i = 0; i < 3; i++) {
            q[6 * k + i] = rho[k][i] - X_B[k][i];
            q[6 * k + 3 + i] = alpha[k][i];
            qd[6 * k + i] = u[k][i] + rxW[i];
            double s = 0.0;
            for (int j = 0; j < 3; j++)
                s += H[k][i][j] * c[j];
            qd[6 * k + 3 + i] = s;
        }
    }
    for (int i = 0; i < nm; i++) {
        q[6 * nb + i] = p[cfg[6 + i]];
        qd[6 * nb + i] = yd[cfg[6 + i]];
    }
    const double *r = v + 6, *rdot = vdot + 6;
    /* ---- residual rows */
    for (int i = 0; i < 3; i++) {
        F[i] = x0dot[i] - v[i];     /* (69b) */
        F[3 + i] = W0[i] - v[3 + i]; /* (69d) */
    }
    double (*GW)[n] = (double (*)[n])w->GW;
    if (gyro & FFRF_CORIOLIS)
        for (int i = 0; i < n; i++)
            for (int j = 0; j < n; j++)
                GW[i][j] = W0[0] * G[0][i][j] + W0[1] * G[1][i][j] + W0[2] * G[2][i][j];
    for (int i = 0; i < n; i++) { /* (79) and (78) */
        double s1 = 0.0, s2 = 0.0;
        for (int j = 0; j < n; j++) {
            s1 += Me[i][j] * (qd[j] - r[j]);
            s2 += Ke[i][j] * q[j] + Me[i][j] * rdot[j];
            if (gyro & FFRF_CORIOLIS) {
                s1 += GW[i][j] * q[j];
                s2 += GW[i][j] * r[j];
            }
            if (damped) /* structural damping on the co-rotated rates (91), runtime/damping.py */
                s2 += De[i][j] * qd[j];
        }
        F[6 + i] = s1;
        g[i] = s2;
    }
    double *h = w->h, *torque = w->torque;
    for (int i = 0; i < 3; i++) {
        double s1 = 0.0, s2 = 0.0;
        for (int j = 0; j < 3; j++) {
            s1 += Je[i][j] * v[3 + j];
            s2 += Je[i][j] * vdot[3 + j];
        }
        h[i] = s1;
        torque[i] = s2;
    }
    if (gyro) { /* G_k q, G_k qdot; s_k = r^T G_k q (55), sdot_k = rdot^T G_k q + r^T G_k qdot */
        double (*Gq)[n] = (double (*)[n])w->Gq, (*Gqd)[n] = (double (*)[n])w->Gqd;
        for (int kk = 0; kk < 3; kk++) {
            for (int i = 0; i < n; i++) {
                double s1 = 0.0, s2 = 0.0;
                for (int j = 0; j < n; j++) {
                    s1 += G[kk][i][j] * q[j];
                    s2 += G[kk][i][j] * qd[j];
                }
                Gq[kk][i] = s1;
                Gqd[kk][i] = s2;
            }
            if (gyro & FFRF_COUPLING) {
                double s = 0.0, sd = 0.0;
                for (int i = 0; i < n; i++) {
                    s += r[i] * Gq[kk][i];
                    sd += rdot[i] * Gq[kk][i] + r[i] * Gqd[kk][i];
                }
                h[kk] += s;
                torque[kk] += sd;
            }
        }
    }
    const int ex0 = nv, eT0 = nv + 3, eeta = nv + 6;
    if (stiff) /* geometric stiffening (runtime/stiffening.py elastic_force): g += f_vk(q) - f0(Omega0) */
        stiff_force(b, e, q, v + 3, g, w);
    ffrf_cross(W0, h, w->v3);
    for (int i = 0; i < 3; i++) {
        F[eT0 + i] = torque[i] + w->v3[i];                     /* (77) */
        F[ex0 + i] = mass[e] * vdot[i] - mass[e] * gravity[i]; /* (69a) */
    }
    for (int i = 0; i < nm; i++)
        F[eeta + i] = g[6 * nb + i];
    for (int k = 0; k < nb; k++) { /* g_B through (91) */
        const int exP = nv + 6 + nm + 6 * k, eTP = nv + 9 + nm + 6 * k;
        for (int i = 0; i < 3; i++) {
            double s1 = 0.0, s2 = 0.0;
            for (int j = 0; j < 3; j++) {
                s1 += R0[i][j] * g[6 * k + j];
                s2 += H[k][j][i] * g[6 * k + 3 + j];
            }
            F[exP + i] = s1;
            F[ex0 + i] -= s1;
            F[eTP + i] = s2;
            fa[k][i] = s2;
        }
        ffrf_cross(rho[k], g + 6 * k, w->v3);
        for (int i = 0; i < 3; i++) {
            double s = 0.0;
            for (int j = 0; j < 3; j++)
                s += Q[k][i][j] * fa[k][j];
            F[eT0 + i] -= w->v3[i] + s;
        }
    }
    if (stiff) { /* stiffening.rotation_rows: W0 x (Jq Omega0) + Jq Omega0dot + Jqd Omega0, Jq = W1 q [+ q W2 q] */
        const double *Om = v + 3, *Omd = vdot + 3;
        const double (*W1)[3][3] = (const double (*)[3][3])b->data.W1 + (size_t)e * b->dims.n_w1;
        double (*Jq)[3] = (double (*)[3])w->Jq, (*Jqd)[3] = (double (*)[3])w->Jqd;
        double (*HQ)[n] = (double (*)[n])w->HQ;
        const double (*Z)[n] = (const double (*)[n])w->Z;
        weighted_sums(n, q, qd, W1, Jq, Jqd);
        for (int a = 0; a < 3; a++)
            for (int j = 0; j < n; j++)
                HQ[a][j] = Z[a][j]; /* dh/dq = Z [+ V_j Omega0] */
        if (n2 > 0) { /* V_j = sum_l q_l (W2_jl + W2_lj), Vd_j the same with qdot (deformed_inertia) */
            const double (*W2)[n2][3][3] = (const double (*)[n2][3][3])b->data.W2 + (size_t)e * n2;
            double (*V)[3][3] = (double (*)[3][3])w->V, (*Vd)[3][3] = (double (*)[3][3])w->Vd;
            for (int j = 0; j < n; j++)
                for (int a = 0; a < 3; a++)
                    for (int bb = 0; bb < 3; bb++) {
                        double s1 = 0.0, s2 = 0.0;
                        for (int l = 0; l < n; l++) {
                            const double wjl = W2[j][l][a][bb] + W2[l][j][a][bb];
                            s1 += q[l] * wjl;
                            s2 += qd[l] * wjl;
                        }
                        V[j][a][bb] = s1;
                        Vd[j][a][bb] = s2;
                    }
            double qV[3][3], qdV[3][3];
            weighted_sums(n, q, qd, (const double (*)[3][3])V, qV, qdV);
            for (int a = 0; a < 3; a++) {
                for (int bb = 0; bb < 3; bb++) {
                    Jq[a][bb] += 0.5 * qV[a][bb]; /* q W2 q = 1/2 sum_j q_j V_j */
                    Jqd[a][bb] += qdV[a][bb];
                }
                for (int j = 0; j < n; j++) {
                    double s = 0.0;
                    for (int bb = 0; bb < 3; bb++)
                        s += V[j][a][bb] * Om[bb];
                    HQ[a][j] += s;
                }
            }
        }
        for (int a = 0; a < 3; a++) {
            double s = 0.0;
            for (int bb = 0; bb < 3; bb++)
                s += Jq[a][bb] * Om[bb];
            w->hs[a] = s;
        }
        ffrf_cross(W0, w->hs, w->v3);
        for (int a = 0; a < 3; a++) {
            double s = w->v3[a];
            for (int bb = 0; bb < 3; bb++)
                s += Jq[a][bb] * Omd[bb] + Jqd[a][bb] * Om[bb];
            F[eT0 + a] += s;
        }
    }
    if (jac)
        jacobian(b, e, R0, w, jac == 2, Fz, Fy);
}

void ffrf_evaluate(const ffrf_body *b, ffrf_se_work *w, const double *f_load_, const double *t_load_,
                   const double *p, const double *yd, const double *R_, const double *theta_, int jac,
                   double beta, double *F, double *JT_, double *Fl, double *Fz_, double *Fy_, double *T_)
{
    const int N = b->dims.N, E = b->dims.E, nc = b->dims.nc, nv = b->dims.nv, nb = b->dims.nb;
    const int nf = b->dims.nf, nm = b->dims.nm, ny = b->dims.ny, ncv = nc + nv;
    const idx_t (*cfg)[nc] = (const idx_t (*)[nc])b->data.cfg_map, (*vel)[nv] = (const idx_t (*)[nv])b->data.vel_map;
    const idx_t (*nodes)[nb] = (const idx_t (*)[nb])b->data.se_nodes;
    const idx_t *newton_pos = b->data.newton_pos;
    const double (*f_load)[3] = (const double (*)[3])f_load_, (*t_load)[3] = (const double (*)[3])t_load_;
    const double (*R)[3][3] = (const double (*)[3][3])R_, (*theta)[3] = (const double (*)[3])theta_;
    double (*T)[3][3] = (double (*)[3][3])T_;
    double (*JT)[nf] = (double (*)[nf])JT_;
    double (*Fy)[ncv] = (double (*)[ncv])Fy_;
    memset(F, 0, sizeof(double) * (size_t)ny);
    if (jac) {
        for (int r = 0; r < N + E; r++)
            ffrf_tangent(theta[r], &T[r][0][0]);
    }
    double *tmp = w->v3b;
    for (int e = 0; e < E; e++) {
        ffrf_superelement(b, e, p, yd, R_, jac ? 2 : 0, Fl, Fz_, Fy_, w); /* 2: k_q rows solved by M_bar */
        for (int i = 0; i < nv; i++)
            F[vel[e][i]] += Fl[i];
        for (int i = 0; i < nc; i++)
            F[cfg[e][i]] += Fl[nv + i];
        if (!jac)
            continue;
        /* the local columns' Newton positions, the unknowns among them first (the same additions, in column order) */
        int *cols = w->cols, *locs = w->cols + ncv, nk = 0, *rows = w->rows, *rlocs = w->rows + ncv, nr = 0, nr_own = 0, nr_vel = 0;
        const int node_col = 6 + nm, node_row = nv + 6 + nm; /* the first local column, row of the boundary nodes */
        for (int j = 0; j < ncv; j++) {
            const idx_t gc = j < nc ? newton_pos[cfg[e][j]] : newton_pos[vel[e][j - nc]];
            if (gc < nf) {
                cols[nk] = (int)gc;
                locs[nk++] = j;
            }
        }
        for (int i = 0; i < nv + nc; i++) {
            const idx_t gr = i < nv ? newton_pos[vel[e][i]] : newton_pos[cfg[e][i - nv]];
            if (gr >= nf)
                continue;
            double *fy = Fy[i];
            /* d(configuration) = beta T(h Delta) d(zdot) on rotations: the Theta0 and Theta_P columns times T
             * (those of unknowns: the others are not read; a zero block stays zero) */
            for (int blk = 0; blk < nb + 1; blk++) {
                const int col = blk == 0 ? 3 : 9 + nm + 6 * (blk - 1);
                if (newton_pos[cfg[e][col]] >= nf || (fy[col] == 0.0 && fy[col + 1] == 0.0 && fy[col + 2] == 0.0))
                    continue;
                double (*Tr)[3] = blk == 0 ? T[N + e] : T[nodes[e][blk - 1]];
                for (int j = 0; j < 3; j++) {
                    double s = 0.0;
                    for (int m = 0; m < 3; m++)
                        s += fy[col + m] * Tr[m][j];
                    tmp[j] = s;
                }
                for (int j = 0; j < 3; j++)
                    fy[col + j] = tmp[j];
            }
            rows[nr] = (int)gr;
            rlocs[nr++] = i * ncv; /* (the row's offset in F_y, F_ydot) */
            nr_own += i < node_row;
            nr_vel += i < nv;
        }
        /* JT column by column (its stores close together, F_y and F_ydot read by columns). Superelement e alone
         * writes the entries of its own rows or its own columns: set; the boundary nodes' block J[B, B] (shared
         * with the neighbours, the springs and the loads; zeroed by ffrf_factor_clear): added into. The local
         * order puts the own rows first (velocity, x0, Theta0, eta, then the nodes'). J[V, V], the velocity
         * rows' velocity columns, is not written: factor.c takes it as -beta diag(I, M_bar) by the structure. */
        for (int t = 0; t < nk; t++) {
            double *jt = JT[cols[t]];
            const int l = locs[t], own = l < node_col || l >= nc;
            const double *fy = Fy_ + l, *fz = Fz_ + l;
            for (int r = l >= nc ? nr_vel : 0; r < (own ? nr : nr_own); r++)
                jt[rows[r]] = beta * fy[rlocs[r]] + fz[rlocs[r]];
            for (int r = own ? nr : nr_own; r < nr; r++)
                jt[rows[r]] += beta * fy[rlocs[r]] + fz[rlocs[r]];
        }
    }
    /* loads: -f on node translation rows, -R^T t on node rotation rows; d(-R^T t) = -skew(R^T t) dTheta */
    double (*S)[3] = (double (*)[3])w->S;
    for (int k = 0; k < N; k++) {
        for (int i = 0; i < 3; i++) {
            F[6 * k + i] -= f_load[k][i];
            double s = 0.0;
            for (int j = 0; j < 3; j++)
                s += R[k][j][i] * t_load[k][j];
            tmp[i] = s;
            F[6 * k + 3 + i] -= s;
        }
        if (jac && newton_pos[6 * k + 3] < nf) {
            skew(tmp, S);
            for (int i = 0; i < 3; i++)
                for (int j = 0; j < 3; j++) {
                    double s = 0.0;
                    for (int m = 0; m < 3; m++)
                        s += S[i][m] * T[k][m][j];
                    JT[newton_pos[6 * k + 3 + j]][newton_pos[6 * k + 3 + i]] -= beta * s;
                }
        }
    }
}

int ffrf_body_superelement(ffrf_body *b, int e, const double *p, const double *yd, const double *R, int jac,
                           double *F, double *Fz, double *Fy)
{
    if (!b || !b->work.se || e < 0 || e >= b->dims.E || !p || !yd || !R || !F || (jac && (!Fz || !Fy)))
        return -1;
    ffrf_superelement(b, e, p, yd, R, jac == 2 ? 2 : jac != 0, F, Fz, Fy, b->work.se);
    return 0;
}

int ffrf_body_residual(ffrf_body *b, const double *p, const double *yd, const double *R, int jac, double *F,
                       double *Fz, double *Fy)
{
    if (!b || !b->work.se || !p || !yd || !R || !F || (jac && (!Fz || !Fy)))
        return -1;
    const int E = b->dims.E, nc = b->dims.nc, nv = b->dims.nv;
    const size_t block = (size_t)(nv + nc) * (size_t)(nc + nv);
    double *Fl = b->work.Fl;
    memset(F, 0, sizeof(double) * (size_t)b->dims.ny);
    for (int e = 0; e < E; e++) {
        ffrf_superelement(b, e, p, yd, R, jac != 0, Fl, jac ? Fz + e * block : NULL, jac ? Fy + e * block : NULL, b->work.se);
        const idx_t *cfg = b->data.cfg_map + (size_t)e * nc, *vel = b->data.vel_map + (size_t)e * nv;
        for (int i = 0; i < nv; i++)
            F[vel[i]] += Fl[i];
        for (int i = 0; i < nc; i++)
            F[cfg[i]] += Fl[nv + i];
    }
    return 0;
}
