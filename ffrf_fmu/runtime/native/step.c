/* One generalized-alpha step of a body (the C twin of runtime/integrator.py `_step` and `_commit`,
 * runtime/newton.py `_newton` and `_solve`, and runtime/coupling.py add_springs): the same loops, the same accumulation order and the same Newton
 * decisions, so that the results match the numpy path to round-off.
 *
 * Lie-group generalized-alpha (docs/equations.md, "Integrator"): a_{n+1} = (af/am) ydot + A0, the
 * configuration p = beta ydot + P0 and R = R_n exp(theta), theta = p at the rotation slots (h Delta),
 * beta = h gamma af / am; Newton on ydot_{n+1} with the iteration matrix F_ydot + beta [F_y T, F_v]
 * (ffrf_evaluate), modified Newton with the factorization carried along the rotation of the first CM
 * frame (`_corotated_solve`).
 *
 * No allocation: every array is a field of the body (b->work, b->lu); fixed 3 x 3 locals live on
 * the stack. */
#include <math.h>
#include <string.h>

#include "step.h"
#include "so3.h"
#include "factor.h"
#include "superelement.h"

/* No fused multiply-adds: the results must match the numpy path (which never contracts) to round-off. Clang (and zig cc,
 * which targets the host CPU) contracts within expressions by default; GCC in ISO C mode does not. */
#if defined(__clang__)
#pragma STDC FP_CONTRACT OFF
#endif

/* b = J^-1 F on the unknowns in the Newton order from the factorization (luT, piv) built at the first
 * CM frame's rotation ref (9, row-major), carried along the rigid rotation P = R_now ref^T (integrator
 * `_solve`): the equations are frame-indifferent, rotating every world triplet by P maps J to P J P^T. */
static void corotated_solve(const ffrf_body *bd, const double *luT, const int *piv, const double *ref, const double *R_now,
                            const double *F, const idx_t *newton_idx, int k3, int nf, double *b)
{
    double P[9];
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            P[3 * i + j] = R_now[3 * i] * ref[3 * j] + R_now[3 * i + 1] * ref[3 * j + 1] + R_now[3 * i + 2] * ref[3 * j + 2];
    for (int i = 0; i < nf; i++)
        b[i] = F[newton_idx[i]];
    for (int t3 = 0; t3 < k3; t3 += 3) { /* P^T F on each world triplet */
        double x = b[t3], y = b[t3 + 1], z = b[t3 + 2];
        for (int i = 0; i < 3; i++)
            b[t3 + i] = P[i] * x + P[3 + i] * y + P[6 + i] * z;
    }
    ffrf_factor_solve(bd, luT, piv, b); /* factor.c: by superelements, then the nodes */
    for (int t3 = 0; t3 < k3; t3 += 3) { /* P J_ref^-1 P^T F */
        double x = b[t3], y = b[t3 + 1], z = b[t3 + 2];
        for (int i = 0; i < 3; i++)
            b[t3 + i] = P[3 * i] * x + P[3 * i + 1] * y + P[3 * i + 2] * z;
    }
}

/* out = A B A^T (3 x 3). */
static void conjugate(const double *A, const double *B, double *out)
{
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) {
            double s = 0.0;
            for (int k = 0; k < 3; k++)
                for (int m = 0; m < 3; m++)
                    s += A[3 * i + k] * B[3 * k + m] * A[3 * j + m];
            out[3 * i + j] = s;
        }
}

/* Every world triplet of the ydot-layout vector y rotated by Q, in place (integrator `_rotate_world`). */
static void rotate_world(const idx_t *world_idx, int n_world, const double *Q, double *y)
{
    for (int t = 0; t < n_world; t++) {
        const idx_t *w = world_idx + 3 * t;
        double x0 = y[w[0]], x1 = y[w[1]], x2 = y[w[2]];
        for (int i = 0; i < 3; i++)
            y[w[i]] = Q[3 * i] * x0 + Q[3 * i + 1] * x1 + Q[3 * i + 2] * x2;
    }
}

/* ------------------------------------------------------------------ compliant ports */

/* The spring-dampers of compliant ports (runtime/coupling.py add_springs, the same terms): -f on the
 * node translation rows, -m on the node rotation rows, their derivatives into JT (transposed iteration
 * matrix) when jac, and the loads (force, moment; world) into b->springs.loads. runtime/coupling.py `add_springs`. */
void ffrf_springs_apply(ffrf_body *b, const double *p, const double *yd, const double *R, const double *T, int jac,
                        double beta, double *F, double *JT)
{
    const ffrf_springs *sp = &b->springs;
    const idx_t *newton_pos = b->data.newton_pos;
    const size_t nf = (size_t)b->dims.nf;
    double M[9], A[9], Ainv[9], S[9], phi[3], wb[3], m[3];
    for (int s = 0; s < b->dims.n_springs; s++) {
        idx_t k = b->data.spring_node[s];
        idx_t i0 = 6 * k;
        const double *KC = sp->KC + 12 * s; /* (4, 3): K_t, C_t, K_r, C_r */
        double *load = sp->loads + 6 * k;
        if (b->data.spring_trans[s]) {
            for (int a = 0; a < 3; a++) { /* f = K_t (r_in - x) + C_t (v_in - xdot) */
                double f = KC[a] * (sp->r_in[3 * s + a] - p[i0 + a]) + KC[3 + a] * (sp->v_in[3 * s + a] - yd[i0 + a]);
                F[i0 + a] -= f;
                load[a] = f;
                if (jac) {
                    size_t pos = (size_t)newton_pos[i0 + a];
                    JT[pos * nf + pos] += beta * KC[a] + KC[3 + a];
                }
            }
        }
        if (b->data.spring_rot[s]) {
            const double *Rk = R + 9 * k;
            const double *R_in = sp->R_in + 9 * s, *w_in = sp->w_in + 3 * s;
            for (int a = 0; a < 3; a++) { /* M = R^T R_in, wb = R^T w_in */
                wb[a] = Rk[a] * w_in[0] + Rk[3 + a] * w_in[1] + Rk[6 + a] * w_in[2];
                for (int c = 0; c < 3; c++)
                    M[3 * a + c] = Rk[a] * R_in[c] + Rk[3 + a] * R_in[3 + c] + Rk[6 + a] * R_in[6 + c];
            }
            ffrf_logm(M, phi);
            for (int a = 0; a < 3; a++) { /* m = K_r phi + C_r (R^T w_in - W) */
                m[a] = KC[6 + a] * phi[a] + KC[9 + a] * (wb[a] - yd[i0 + 3 + a]);
                F[i0 + 3 + a] -= m[a];
            }
            for (int a = 0; a < 3; a++)
                load[3 + a] = Rk[3 * a] * m[0] + Rk[3 * a + 1] * m[1] + Rk[3 * a + 2] * m[2];
            if (jac) { /* dm/dTheta = -K_r T(-phi)^-1 + C_r skew(R^T w_in); J += -beta dm T + diag(C_r) */
                for (int a = 0; a < 3; a++)
                    phi[a] = -phi[a];
                ffrf_tangent(phi, A);
                ffrf_inv3(A, Ainv);
                ffrf_skew(wb, S);
                for (int a = 0; a < 3; a++)
                    for (int c = 0; c < 3; c++)
                        A[3 * a + c] = -KC[6 + a] * Ainv[3 * a + c] + KC[9 + a] * S[3 * a + c]; /* dm/dTheta */
                const double *Tk = T + 9 * k;
                for (int a = 0; a < 3; a++) {
                    size_t pa = (size_t)newton_pos[i0 + 3 + a];
                    for (int c = 0; c < 3; c++) {
                        double v = -beta * (A[3 * a] * Tk[c] + A[3 * a + 1] * Tk[3 + c] + A[3 * a + 2] * Tk[6 + c]);
                        if (a == c)
                            v += KC[9 + a];
                        JT[(size_t)newton_pos[i0 + 3 + c] * nf + pa] += v;
                    }
                }
            }
        }
    }
}

/* ------------------------------------------------------------------ Newton */

/* The configuration at the rates yd (integrator `_stage_at`): p = c yd + P0, theta = p at the rotation
 * slots (h Delta), R = Rn exp(theta). */
static void stage_at(const ffrf_body *b, const double *c, const double *P0, const double *Rn, const double *yd,
                     double *p, double *theta, double *R)
{
    const int ny = b->dims.ny, NR = b->dims.N + b->dims.E;
    const idx_t *rot_slots = b->data.rot_slots;
    double Rexp[9];
    for (int i = 0; i < ny; i++)
        p[i] = yd[i] * c[i] + P0[i];
    for (int r = 0; r < NR; r++) {
        double *th = theta + 3 * r;
        const double *Rr = Rn + 9 * r;
        double *Ro = R + 9 * r;
        for (int i = 0; i < 3; i++)
            th[i] = p[rot_slots[3 * r + i]];
        ffrf_expm(th, Rexp);
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < 3; j++)
                Ro[3 * i + j] = Rr[3 * i] * Rexp[j] + Rr[3 * i + 1] * Rexp[3 + j] + Rr[3 * i + 2] * Rexp[6 + j];
    }
}

/* Newton on the rates ydot_{n+1} of one step (runtime/newton.py `_newton`, the same decisions).
 *
 * In: the stage p = c ydot + P0, R = Rn exp(theta) (theta = p at rot_slots); the loads; yd holds the
 * predictor. Out: yd the accepted rates, p, R their configuration, F the residual of the last
 * evaluation (the accepted iterate is not evaluated again); info = [status, iterations]; a refresh at
 * iteration it sets bit it + offset - 1 of lu.refreshed (offset: iterations of a failed attempt). b->lu holds the
 * LU of the iteration matrix across steps (luT transposed: luT^T is scipy's lu_factor LU; piv 0-based;
 * meta = [valid, beta, R_ref (9), verdict: 0 drop, 1 serves, 2 keeps]); a refresh factors the matrix built in lu.JT into lu.luT and
 * increments lu.version. On failure meta[0] = 0 and a status != OK, with the last increment in meta[1]
 * for NOT_CONVERGED.
 * Convergence and refresh as integrator `_newton`: increments scaled per field (field_of), accepted on
 * the contraction estimate theta/(1 - theta) |dx|; serves as there (keep_miss = KEEP_MISS: a first increment
 * beyond it serves, a kept matrix's second increment then does not decide a refresh and its later ones are
 * accepted at kept_accept = KEPT_ACCEPT of the tolerance; trusted: REFRESH_AFTER kept it on its serves verdict). */
static void newton_step(ffrf_body *b, int trusted, const double *c, const double *P0, const double *Rn,
                        const double *f_load, const double *t_load, double beta, double tol, int max_iter, double *yd,
                        double *p, double *R, double *F, int offset, int info[2])
{
    const ffrf_data *D = &b->data;
    ffrf_work *w = &b->work;
    ffrf_lu *L = &b->lu;
    double *lu_meta = L->meta;
    const int N = b->dims.N, NR = b->dims.N + b->dims.E, ny = b->dims.ny, nf = b->dims.nf;
    const int n_fields = b->dims.n_fields;
    const idx_t *newton_idx = D->newton_idx, *field_of = D->field_of;
    const double keep_miss = D->keep_miss, theta_refresh = D->theta_refresh;
    double *theta = w->theta, *T = w->T, *bx = w->b, *S = w->S;
    int kept = 1, far = 0, wide = 0, near = 0, late = 0; /* kept: no matrix built in this step (yet); late: one built after the first */
    double nrm_prev = INFINITY, nrm = 0.0, rate, second = 0.0; /* second: the second increment (KEPT_AGE) */
    int converged = 0;
    int it = 0;
    for (it = 1; it <= max_iter; it++) {
        int refresh = lu_meta[0] == 0.0 || fabs(lu_meta[1] - beta) > 1e-6 * beta;
        stage_at(b, c, P0, Rn, yd, p, theta, R);
        if (refresh)
            ffrf_factor_clear(b, L->JT); /* factor.c: the structural entries ffrf_evaluate adds into */
        ffrf_evaluate(b, w->se, f_load, t_load, p, yd, R, theta, refresh, beta, F, L->JT, w->Fl, w->Fz, w->Fy, T);
        ffrf_springs_apply(b, p, yd, R, T, refresh, beta, F, L->JT);
        double s = 0.0;
        for (int i = 0; i < ny; i++)
            s += F[i] * 0.0;
        if (s != 0.0 || s != s) { /* NaN: some entry of F is not finite */
            lu_meta[0] = 0.0;
            info[0] = FFRF_NOT_FINITE;
            info[1] = it;
            return;
        }
        if (refresh) {
            kept = 0;
            late = it > 1;
            /* the new matrix replaces the factorization: the version tells a caller holding a copy of
             * the old one (a rollback snapshot) that it is not this one any more */
            L->version++;
            if (it + offset <= 64)
                L->refreshed |= (uint64_t)1 << (it + offset - 1);
            int status = ffrf_factor(b, L->JT, beta, L->luT, L->piv); /* -1 also when an entry is not finite */
            if (status != 0) {
                lu_meta[0] = 0.0;
                info[0] = FFRF_NOT_FACTORED;
                info[1] = it;
                return;
            }
            lu_meta[0] = 1.0;
            lu_meta[1] = beta;
            for (int i = 0; i < 9; i++)
                lu_meta[2 + i] = R[9 * N + i];
        }
        corotated_solve(b, L->luT, L->piv, lu_meta + 2, R + 9 * N, F, newton_idx, D->k3, nf, bx);
        for (int i = 0; i < nf; i++)
            yd[newton_idx[i]] -= bx[i];
        for (int f = 0; f < n_fields; f++) /* the largest rate of each field, at the new iterate */
            S[f] = 0.0;
        for (int i = 0; i < nf; i++) {
            double a = fabs(yd[newton_idx[i]]);
            if (a > S[field_of[i]])
                S[field_of[i]] = a;
        }
        nrm = 0.0;
        for (int i = 0; i < nf; i++) {
            double e = fabs(bx[i]) / (tol / beta + tol * S[field_of[i]]);
            if (e > nrm)
                nrm = e;
        }
        rate = nrm / nrm_prev; /* the contraction theta of integrator `_newton` */
        if (it == 1) {
            far = nrm * tol > keep_miss;
            wide = nrm * tol > D->wide_miss;
            near = nrm <= D->near_miss;
        } else if (it == 2) {
            second = nrm;
        }
        /* the error an iterate on an older matrix may leave (KEPT_ACCEPT, WIDE_MISS; 0: not accepted) */
        double lim = !(kept && far) || it == 1 ? 1.0 : it > 2 ? D->kept_accept : wide ? 1.0 : 0.0;
        if (it == 1 ? nrm <= 1.0 : (nrm <= 0.1 * lim || (rate < 1.0 && rate / (1.0 - rate) * nrm <= lim))) {
            converged = 1; /* the accepted iterate's configuration, not evaluated again */
            stage_at(b, c, P0, Rn, yd, p, theta, R);
            break;
        }
        /* slow contraction, or too slow to reach the tolerance in 3 more iterations: refresh; not on the second
         * increment of a kept matrix after a far miss while kept_radius^3 of it is within kept_accept (the transient
         * of its error; integrator `_newton`) */
        double r2 = rate * rate, kr = D->kept_radius;
        if (it > 1 && !(it == 2 && kept && far && kr * kr * kr * nrm <= D->kept_accept) &&
            (rate > theta_refresh || r2 * r2 / (1.0 - rate) * nrm > lim || (trusted && kept)))
            lu_meta[0] = 0.0;
        nrm_prev = nrm;
    }
    if (!converged) {
        it = max_iter; /* (Python's loop variable keeps its last value) */
        lu_meta[0] = 0.0;
        lu_meta[1] = nrm_prev;
        info[0] = FFRF_NOT_CONVERGED;
        info[1] = it;
        return;
    }
    for (int r = 0; r < NR; r++) { /* integrator `_check_rotation_increments` */
        const double *th = theta + 3 * r;
        if (th[0] * th[0] + th[1] * th[1] + th[2] * th[2] > FFRF_PI * FFRF_PI) {
            lu_meta[0] = 0.0;
            info[0] = FFRF_ROTATION_ALIAS;
            info[1] = it;
            return;
        }
    }
    info[0] = FFRF_OK;
    info[1] = it;
    lu_meta[11] = far && !late && (wide || second <= D->kept_age) ? 1.0 : (it == 2 && near && rate <= D->near_contraction) ? 2.0 : 0.0; /* SERVES, KEEPS */
}

/* ------------------------------------------------------------------ one step */

/* One whole step t -> t + h (integrator `_step` with `_prepare_step`, `_commit`, body
 * `_update_port_loads`, `_external_power`): the state arrays and the energy
 * [work, power] are updated in place, and only if Newton succeeded; so is b->state.iterations (the
 * step's iterations, a retry's failed attempt counted). The inputs are those of b->in (read by
 * `BodySystem._read_inputs`: current frames where no motion input); last_it the iterations of the last
 * step (the refresh rule REFRESH_AFTER = (refresh_min, refresh_max)). The time b->state.t is the
 * caller's (ffrf_body_advance). Returns the status (FFRF_OK ...). */
int ffrf_step(ffrf_body *b, double h, int last_it)
{
    const ffrf_data *D = &b->data;
    const ffrf_dims *d = &b->dims;
    ffrf_state *st = &b->state;
    ffrf_work *w = &b->work;
    double *lu_meta = b->lu.meta;
    const int N = d->N, E = d->E, ny = d->ny;
    const double am = b->am, af = b->af, gamma = b->gamma;
    double *ydw = w->ydw, *p = w->p, *R = w->R, *F = w->F, *A0 = w->A0, *P0 = w->P0, *c = w->c, *Rn = w->Rn;
    double *xN = st->xN, *RN = st->RN, *x0 = st->x0, *R0 = st->R0, *eta = st->eta, *v = st->v;
    double *yd = st->yd, *yd_prev = st->yd_prev, *yd_prev2 = st->yd_prev2, *a = st->a;
    const double *xN_p = b->in.xN_p, *RN_p = b->in.RN_p, *zN_p = b->in.zN_p;
    const double *f_in = b->in.f_in, *t_in = b->in.t_in;
    int info[2] = {FFRF_OK, 0};
    double beta = h * gamma * af / am;
    /* stage (integrator `_prepare_step`): a_{n+1} = (af/am) ydot + A0, p = beta ydot + P0 */
    double c1 = (1.0 - af) / am, c2 = -(1.0 - am) / am;
    double d1 = h * gamma * c1, d2 = h * (1.0 - gamma) + h * gamma * c2;
    for (int i = 0; i < ny; i++) {
        A0[i] = c1 * yd[i] + c2 * a[i];
        P0[i] = d1 * yd[i] + d2 * a[i];
        c[i] = beta * D->stage_mask[i];
        ydw[i] = (yd[i] - yd_prev[i]) * 3.0 + yd_prev2[i]; /* predictor: quadratic extrapolation of the rates */
    }
    /* ... its world triplets rotated with the first CM frame over the step (integrator `_predicted_rotation`) */
    double Q[9], Rexp[9], th[3];
    for (int i = 0; i < 3; i++) {
        idx_t slot = D->rot_slots[3 * N + i];
        th[i] = beta * ydw[slot] + P0[slot];
    }
    ffrf_expm(th, Rexp);
    conjugate(R0, Rexp, Q);
    rotate_world(D->world_idx, d->n_world, Q, ydw);
    {
        int k = 0;
        const double *arrs[4] = {xN, x0, eta, v};
        const int sizes[4] = {3 * N, 3 * E, E * d->nm, E * d->nv};
        for (int q = 0; q < 4; q++)
            for (int i = 0; i < sizes[q]; i++)
                P0[D->lin_slots[k++]] += arrs[q][i];
    }
    for (int j = 0; j < d->n_mx; j++)
        for (int i = 0; i < 3; i++)
            P0[D->motion_x_slots[3 * j + i]] = xN_p[3 * D->motion_x[j] + i];
    for (int i = 0; i < d->n_mT; i++)
        P0[D->motion_T_slots[i]] = 0.0;
    for (int i = 0; i < d->n_fixed; i++)
        ydw[D->fixed_idx[i]] = zN_p[D->fixed_idx[i]];
    memcpy(Rn, RN_p, (size_t)9 * N * sizeof(double));
    memcpy(Rn + 9 * N, R0, (size_t)9 * E * sizeof(double));
    /* the predictor missed at the last step and the matrix is not known to serve: a fresh one, unless the last step
     * kept it (KEEPS: a near miss on a matrix that contracts; integrator `_step`) */
    int after = D->refresh_min <= last_it && last_it <= D->refresh_max && lu_meta[0] != 0.0 && lu_meta[11] != 2.0;
    int trusted = after && lu_meta[11] == 1.0;
    if (after && lu_meta[11] == 0.0) /* dropped */
        lu_meta[0] = 0.0;
    b->lu.refreshed = 0;
    /* a hard real-time bound (iteration_cap, solver.max_newton_iterations): the iterations of both attempts
     * together at most the cap, the loop itself bounded so that no step iterates past it */
    const int cap = b->iteration_cap > 0 && b->iteration_cap < 2 * b->max_iter ? b->iteration_cap : 2 * b->max_iter;
    for (int attempt = 0; attempt < 2 && cap > attempt * b->max_iter; attempt++) {
        int n_it = cap - attempt * b->max_iter < b->max_iter ? cap - attempt * b->max_iter : b->max_iter;
        newton_step(b, trusted, c, P0, Rn, f_in, t_in, beta, b->tol, n_it, ydw, p, R, F, attempt * b->max_iter, info);
        if (attempt == 1)
            info[1] += b->max_iter; /* the failed attempt's iterations count */
        if (info[0] == FFRF_OK || info[0] == FFRF_ROTATION_ALIAS || attempt == 1)
            break;
        /* one retry from the last step's rates with a fresh matrix (integrator `_step`) */
        for (int i = 0; i < ny; i++)
            ydw[i] = yd[i];
        for (int i = 0; i < d->n_fixed; i++)
            ydw[D->fixed_idx[i]] = zN_p[D->fixed_idx[i]];
        lu_meta[0] = 0.0;
        trusted = 0;
    }
    if (info[0] == FFRF_NOT_CONVERGED && cap < 2 * b->max_iter)
        return FFRF_ITERATION_CAP;
    if (info[0] != FFRF_OK)
        return info[0];
    /* commit (integrator `_commit`) */
    {
        int k = 0;
        double *arrs[4] = {xN, x0, eta, v};
        const int sizes[4] = {3 * N, 3 * E, E * d->nm, E * d->nv};
        for (int q = 0; q < 4; q++)
            for (int i = 0; i < sizes[q]; i++)
                arrs[q][i] = p[D->lin_slots[k++]];
    }
    for (int i = 0; i < 3; i++) /* the rotation of the first CM frame over the step, R_{n+1} R_n^T */
        for (int j = 0; j < 3; j++)
            Q[3 * i + j] = R[9 * N + 3 * i] * R0[3 * j] + R[9 * N + 3 * i + 1] * R0[3 * j + 1] +
                           R[9 * N + 3 * i + 2] * R0[3 * j + 2];
    memcpy(RN, R, (size_t)9 * N * sizeof(double));
    memcpy(R0, R + 9 * N, (size_t)9 * E * sizeof(double));
    double af_am = af / am;
    for (int i = 0; i < ny; i++) {
        yd_prev2[i] = yd_prev[i];
        yd_prev[i] = yd[i];
        yd[i] = ydw[i];
        a[i] = af_am * ydw[i] + A0[i];
    }
    rotate_world(D->world_idx, d->n_world, Q, yd_prev2); /* the history carried along with the body (integrator `_commit`) */
    rotate_world(D->world_idx, d->n_world, Q, yd_prev);
    /* port loads (body `_update_port_loads`) and the power of loads and gravity (`_external_power`) */
    const double *spring_loads = b->springs.loads; /* force, moment of compliant ports' springs (zero on other nodes) */
    double *fN = st->fN, *tN = st->tN, *energy = st->energy;
    double power = 0.0;
    for (int n = 0; n < N; n++) {
        const double *mp = D->motion_parts + 6 * n, *sl = spring_loads + 6 * n, *RNn = RN + 9 * n;
        for (int i = 0; i < 3; i++) {
            fN[3 * n + i] = f_in[3 * n + i] + mp[i] * F[6 * n + i] + sl[i];
            double s = 0.0;
            for (int j = 0; j < 3; j++)
                s += RNn[3 * i + j] * F[6 * n + 3 + j];
            tN[3 * n + i] = t_in[3 * n + i] + mp[3 + i] * s + sl[3 + i];
        }
        for (int i = 0; i < 3; i++) {
            double s = 0.0;
            for (int j = 0; j < 3; j++)
                s += RNn[3 * j + i] * tN[3 * n + j];
            power += fN[3 * n + i] * yd[6 * n + i] + s * yd[6 * n + 3 + i];
        }
    }
    for (int e = 0; e < E; e++)
        for (int i = 0; i < 3; i++)
            power += D->mass[e] * v[(size_t)e * d->nv + i] * D->gravity[i];
    energy[0] += 0.5 * h * (energy[1] + power);
    energy[1] = power;
    st->iterations = info[1];
    return FFRF_OK;
}
