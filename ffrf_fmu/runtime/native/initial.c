/* A body's consistent initial state at t0 (runtime/initial_conditions.py `BodySystem.initialize`, the same
 * steps on the C runtime's body): the reference configuration moved rigidly onto the motion inputs, optional
 * port displacements relaxed to a static shape (`_relax`), the rigid velocity field v + w x (x - origin) (or
 * the motion inputs' rates), then consistent rates ydot_0 from a backward-Euler micro-step
 * (am = af = gamma = 1) whose configuration rates are replaced by the exact ones at t0, and the port
 * loads and external power at t0. The standalone run (runtime/native/binding.py) and the FMU
 * (fmu/native/initialize.c) both start their bodies here, each with its own inputs (ffrf_runtime.h).
 *
 * The body must be at its reference state (as created, or set back to it). Memory: a few work arrays
 * allocated here (initialization, not a step). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "body.h"
#include "initial.h"

#define MOTION 1 /* port_mode: 0 force, 1 motion, 2 compliant */
#define RELAX_TOL 1e-12

/* p (global ydot layout) of the current configuration: positions, eta and velocities in their stage slots,
 * rotation increments 0; R the node then CM frames. */
static void stage_of_state(const ffrf_body *b, double *p, double *R)
{
    const ffrf_dims *d = &b->dims;
    const ffrf_state *st = &b->state;
    memset(p, 0, sizeof(double) * (size_t)d->ny);
    const double *arrs[4] = {st->xN, st->x0, st->eta, st->v};
    const int sizes[4] = {3 * d->N, 3 * d->E, d->E * d->nm, d->E * d->nv};
    for (int q = 0, k = 0; q < 4; q++)
        for (int i = 0; i < sizes[q]; i++)
            p[b->data.lin_slots[k++]] = arrs[q][i];
    memcpy(R, st->RN, sizeof(double) * 9 * (size_t)d->N);
    memcpy(R + 9 * d->N, st->R0, sizeof(double) * 9 * (size_t)d->E);
}

/* A x = rhs with the runtime's LU (lu.c, LAPACK dgetf2's order; A n x n stored transposed, destroyed): 0, or -1
 * for a singular A or a non-finite x */
static int solve_dense(double *AT, int *piv, double *x, int n)
{
    if (ffrf_lu_factor(AT, piv, n) != 0)
        return -1;
    ffrf_lu_solve(AT, piv, x, n);
    for (int i = 0; i < n; i++)
        if (!isfinite(x[i]))
            return -1;
    return 0;
}

/* The residual without inertia or loads and its configuration derivative F_y on the Newton unknowns
 * (JT(beta) = (F_ydot + beta F_y T)^T is affine in beta; at zero rates and zero rotation increments
 * T = I, so F_y = J(1) - J(0)). Fy: [nf][nf] row-major, J itself. */
static void static_jacobian(ffrf_body *b, double *p, const double *yd, const double *R, const double *theta,
                            const double *zero_loads, double *F, double *Fy)
{
    ffrf_work *w = &b->work;
    const size_t nf = (size_t)b->dims.nf;
    double *JT = b->lu.JT;
    ffrf_factor_clear(b, JT);
    ffrf_evaluate(b, w->se, zero_loads, zero_loads, p, yd, R, theta, 1, 0.0, F, JT, w->Fl, w->Fz, w->Fy, w->T);
    for (size_t r = 0; r < nf; r++) /* JT is transposed: J[r][c] = JT[c][r] */
        for (size_t c = 0; c < nf; c++)
            Fy[r * nf + c] = -JT[c * nf + r];
    ffrf_factor_clear(b, JT);
    ffrf_evaluate(b, w->se, zero_loads, zero_loads, p, yd, R, theta, 1, 1.0, F, JT, w->Fl, w->Fz, w->Fy, w->T);
    for (size_t r = 0; r < nf; r++)
        for (size_t c = 0; c < nf; c++)
            Fy[r * nf + c] += JT[c * nf + r];
}

/* BodySystem._relax: static equilibrium (no inertia, loads or gravity) with every undisplaced port's
 * translation and rotation fixed and each displaced port fixed only along its displacement u (a Lagrange
 * multiplier per displaced port), Newton on the configuration. */
static int relax(ffrf_body *b, const double *disp, double *last_out)
{
    const ffrf_dims *d = &b->dims;
    const ffrf_data *D = &b->data;
    ffrf_state *st = &b->state;
    const int N = d->N, E = d->E, nm = d->nm, ny = d->ny, nf = d->nf;
    const int n_cfg = 6 * N + E * (6 + nm);
    int n_ports = d->n_ports;
    int *free_slot = calloc((size_t)ny, sizeof(int));
    int *idx = malloc(sizeof(int) * (size_t)ny);
    double *dirs = calloc((size_t)(n_ports ? n_ports : 1) * (size_t)ny, sizeof(double));
    double *p = malloc(sizeof(double) * (size_t)ny), *yd0 = calloc((size_t)ny, sizeof(double));
    double *R = malloc(sizeof(double) * 9 * (size_t)(N + E)), *theta = calloc(3 * (size_t)(N + E), sizeof(double));
    double *F = malloc(sizeof(double) * (size_t)ny), *Fy = malloc(sizeof(double) * (size_t)nf * (size_t)nf);
    double *zero = calloc(3 * (size_t)N, sizeof(double)), *delta = calloc((size_t)ny, sizeof(double));
    size_t nA = (size_t)ny + (size_t)n_ports;
    double *A = malloc(sizeof(double) * nA * nA), *x = malloc(sizeof(double) * nA);
    int *piv = malloc(sizeof(int) * nA);
    double *v_saved = malloc(sizeof(double) * (size_t)(E * d->nv) + 8);
    int status = FFRF_INIT_NO_MEMORY;
    if (!free_slot || !idx || !dirs || !p || !yd0 || !R || !theta || !F || !Fy || !zero || !delta || !A || !x ||
        !piv || !v_saved)
        goto done;
    status = FFRF_INIT_NO_EQUILIBRIUM;
    double gravity[3];
    double *g = (double *)D->gravity;
    memcpy(gravity, g, sizeof gravity);
    memset(g, 0, sizeof gravity);
    memcpy(v_saved, st->v, sizeof(double) * (size_t)(E * d->nv));
    memset(st->v, 0, sizeof(double) * (size_t)(E * d->nv));
    for (int i = 0; i < n_cfg; i++)
        free_slot[i] = 1;
    int n_rows = 0;
    for (int j = 0; j < n_ports; j++) { /* ports in model order */
        idx_t node = D->port_node[j];
        const double *u = disp + 3 * j;
        double norm = sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]);
        if (norm == 0.0) {
            for (int i = 0; i < 3; i++)
                free_slot[6 * node + i] = 0;
        } else {
            for (int i = 0; i < 3; i++)
                dirs[(size_t)n_rows * ny + 6 * node + i] = u[i] / norm;
            n_rows++;
        }
        /* an undisplaced port (a zero displacement parameter, or none: its translation not force-driven) keeps its
         * rotation too, as a port the scene does not displace (body.py `_relax`); only a displaced one turns */
        if (norm == 0.0 || D->port_mode[2 * j + 1] == MOTION)
            for (int i = 3; i < 6; i++)
                free_slot[6 * node + i] = 0;
    }
    int n_idx = 0;
    for (int i = 0; i < ny; i++)
        if (free_slot[i])
            idx[n_idx++] = i;
    double last = 0.0;
    for (int it = 0; it < FFRF_RELAX_MAX_ITER; it++) {
        stage_of_state(b, p, R);
        static_jacobian(b, p, yd0, R, theta, zero, F, Fy);
        const int n = n_idx + n_rows;
        for (int r = 0; r < n; r++)
            for (int c = 0; c < n; c++) {
                double v = 0.0;
                if (r < n_idx && c < n_idx) {
                    idx_t pr = D->newton_pos[idx[r]], pc = D->newton_pos[idx[c]];
                    v = (pr < nf && pc < nf) ? Fy[pr * nf + pc] : (r == c ? 1.0 : 0.0);
                } else if (r < n_idx) {
                    v = dirs[(size_t)(c - n_idx) * ny + idx[r]];
                } else if (c < n_idx) {
                    v = dirs[(size_t)(r - n_idx) * ny + idx[c]];
                }
                A[(size_t)c * n + r] = v; /* transposed, as lu.c stores it */
            }
        for (int r = 0; r < n; r++)
            x[r] = r < n_idx ? -F[idx[r]] : 0.0;
        memset(delta, 0, sizeof(double) * (size_t)ny);
        if (solve_dense(A, piv, x, n) != 0) { /* the fixed parts leave the body a mechanism: no unique shape */
            last = INFINITY;
            break;
        }
        last = 0.0;
        for (int r = 0; r < n_idx; r++) {
            delta[idx[r]] = x[r];
            last = fmax(last, fabs(x[r]));
        }
        /* the configuration moved by delta (integrator `_configuration`): positions and eta added, R <- R expm */
        for (int k = 0; k < N; k++) {
            double rot[9], Rn[9];
            for (int i = 0; i < 3; i++)
                st->xN[3 * k + i] += delta[6 * k + i];
            ffrf_expm(delta + 6 * k + 3, rot);
            for (int r = 0; r < 3; r++)
                for (int c = 0; c < 3; c++)
                    Rn[3 * r + c] = st->RN[9 * k + 3 * r] * rot[c] + st->RN[9 * k + 3 * r + 1] * rot[3 + c] +
                                    st->RN[9 * k + 3 * r + 2] * rot[6 + c];
            memcpy(st->RN + 9 * k, Rn, sizeof Rn);
        }
        for (int e = 0; e < E; e++) {
            const double *dS = delta + 6 * N + e * (6 + nm);
            double rot[9], Rn[9];
            for (int i = 0; i < 3; i++)
                st->x0[3 * e + i] += dS[i];
            ffrf_expm(dS + 3, rot);
            for (int r = 0; r < 3; r++)
                for (int c = 0; c < 3; c++)
                    Rn[3 * r + c] = st->R0[9 * e + 3 * r] * rot[c] + st->R0[9 * e + 3 * r + 1] * rot[3 + c] +
                                    st->R0[9 * e + 3 * r + 2] * rot[6 + c];
            memcpy(st->R0 + 9 * e, Rn, sizeof Rn);
            for (int i = 0; i < nm; i++)
                st->eta[e * nm + i] += dS[6 + i];
        }
        if (last < RELAX_TOL) {
            status = 0;
            break;
        }
    }
    memcpy(g, gravity, sizeof gravity);
    memcpy(st->v, v_saved, sizeof(double) * (size_t)(E * d->nv));
    *last_out = last;
done:
    free(free_slot);
    free(idx);
    free(dirs);
    free(p);
    free(yd0);
    free(R);
    free(theta);
    free(F);
    free(Fy);
    free(zero);
    free(delta);
    free(A);
    free(x);
    free(piv);
    free(v_saved);
    return status;
}

/* The port loads at t0 (the inputs, the reactions on motion parts, the springs: body `_update_port_loads`),
 * the external power, no work done yet, no factorization kept: the end of an initialization from the state
 * as it is (runtime/start.py `finish`). p, R, theta: work of the stage's sizes (ny; 9 (N + E); 3 (N + E), zero). */
static void port_loads(ffrf_body *b, double *p, double *R, const double *theta)
{
    const ffrf_dims *d = &b->dims;
    const ffrf_data *D = &b->data;
    ffrf_state *st = &b->state;
    const int N = d->N, E = d->E, nv = d->nv;
    stage_of_state(b, p, R);
    double *F = b->work.F;
    ffrf_evaluate(b, b->work.se, b->in.f_in, b->in.t_in, p, st->yd, R, theta, 0, 0.0, F, NULL, b->work.Fl, b->work.Fz,
                  b->work.Fy, b->work.T);
    memset(b->springs.loads, 0, sizeof(double) * 6 * (size_t)N);
    if (d->n_springs)
        ffrf_springs_apply(b, p, st->yd, R, b->work.T, 0, 0.0, F, NULL);
    double power = 0.0;
    for (int k = 0; k < N; k++) {
        const double *mp = D->motion_parts + 6 * k, *sl = b->springs.loads + 6 * k, *Rk = st->RN + 9 * k;
        for (int i = 0; i < 3; i++) {
            st->fN[3 * k + i] = b->in.f_in[3 * k + i] + mp[i] * F[6 * k + i] + sl[i];
            double s = Rk[3 * i] * F[6 * k + 3] + Rk[3 * i + 1] * F[6 * k + 4] + Rk[3 * i + 2] * F[6 * k + 5];
            st->tN[3 * k + i] = b->in.t_in[3 * k + i] + mp[3 + i] * s + sl[3 + i];
        }
        for (int i = 0; i < 3; i++) {
            double s = Rk[i] * st->tN[3 * k] + Rk[3 + i] * st->tN[3 * k + 1] + Rk[6 + i] * st->tN[3 * k + 2];
            power += st->fN[3 * k + i] * st->yd[6 * k + i] + s * st->yd[6 * k + 3 + i];
        }
    }
    for (int e = 0; e < E; e++)
        for (int i = 0; i < 3; i++)
            power += D->mass[e] * st->v[(size_t)e * nv + i] * D->gravity[i];
    st->energy[0] = 0.0;
    st->energy[1] = power;
    st->iterations = 0;
    b->lu.meta[0] = 0.0;
}

int ffrf_port_loads_at(ffrf_body *b, double t0)
{
    const size_t N = (size_t)b->dims.N, E = (size_t)b->dims.E;
    double *p = malloc(sizeof(double) * (size_t)b->dims.ny), *R = malloc(sizeof(double) * 9 * (N + E));
    double *theta = calloc(3 * (N + E), sizeof(double));
    int status = -1;
    if (p && R && theta) {
        ffrf_extrapolated_inputs(b, t0, t0);
        port_loads(b, p, R, theta);
        status = 0;
    }
    free(p);
    free(R);
    free(theta);
    return status;
}

/* FFRF_GIVEN's inputs (ffrf_runtime.h): the inputs arrays, then the compliant ports' far ends */
static size_t input_count(const ffrf_body *b)
{
    return 24 * (size_t)b->dims.N + 18 * (size_t)b->dims.n_springs;
}

/* the body's inputs out into buf (back = 0) or back in from it (back = 1) */
static void inputs_io(ffrf_body *b, double *buf, int back)
{
    const size_t N = (size_t)b->dims.N, ns = (size_t)b->dims.n_springs;
    double *arrs[9] = {b->in.xN_p, b->in.RN_p, b->in.zN_p, b->in.f_in, b->in.t_in,
                       b->springs.r_in, b->springs.v_in, b->springs.R_in, b->springs.w_in};
    const size_t sizes[9] = {3 * N, 9 * N, 6 * N, 3 * N, 3 * N, 3 * ns, 3 * ns, 9 * ns, 3 * ns};
    for (int q = 0; q < 9; buf += sizes[q], q++)
        if (sizes[q])
            memcpy(back ? arrs[q] : buf, back ? buf : arrs[q], sizeof(double) * sizes[q]);
}

/* the caller's inputs of the micro-step in, the nodes without a motion-driven translation (rotation) at their
 * current position (frame), as BodySystem._read_inputs reads them */
static void given_inputs(ffrf_body *b, const double *next)
{
    const ffrf_state *st = &b->state;
    inputs_io(b, (double *)next, 1);
    for (int k = 0; k < b->dims.N; k++) {
        const double *mp = b->data.motion_parts + 6 * k;
        if (mp[0] == 0.0)
            memcpy(b->in.xN_p + 3 * k, st->xN + 3 * k, 3 * sizeof(double));
        if (mp[3] == 0.0)
            memcpy(b->in.RN_p + 9 * k, st->RN + 9 * k, 9 * sizeof(double));
    }
}

int ffrf_body_initialize(ffrf_body *b, double t0, const double velocity[3], const double angular_velocity[3],
                         const double origin[3], const double *port_displacements, int kind, const double *next,
                         double *last)
{
    const ffrf_dims *d = &b->dims;
    const ffrf_data *D = &b->data;
    ffrf_state *st = &b->state;
    const int N = d->N, E = d->E, nm = d->nm, nv = d->nv, ny = d->ny;
    const int n_cfg = 6 * N + E * (6 + nm);
    size_t state_size = ffrf_body_state_size(b);
    double *saved = malloc(sizeof(double) * state_size), *yd0 = malloc(sizeof(double) * (size_t)ny);
    double *p = malloc(sizeof(double) * (size_t)ny), *R = malloc(sizeof(double) * 9 * (size_t)(N + E));
    double *theta = calloc(3 * (size_t)(N + E), sizeof(double));
    const size_t n_in = input_count(b);
    double *at_t0 = kind == FFRF_GIVEN ? malloc(sizeof(double) * n_in) : NULL;
    int status = FFRF_INIT_NO_MEMORY;
    *last = 0.0;
    if (!saved || !yd0 || !p || !R || !theta || (kind == FFRF_GIVEN && !at_t0))
        goto done;
    st->t = t0;
    if (kind == FFRF_GIVEN)
        inputs_io(b, at_t0, 0);
    else
        ffrf_extrapolated_inputs(b, t0, t0);
    const double *xN_p = b->in.xN_p, *RN_p = b->in.RN_p, *zN_p = b->in.zN_p;
    /* rigid placement on the first motion-driven rotation (then translation) input */
    double Rr[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1}, c_ref[3] = {0, 0, 0}, c_new[3] = {0, 0, 0};
    double v_lin[3], w[3], o[3];
    memcpy(v_lin, velocity, sizeof v_lin);
    memcpy(w, angular_velocity, sizeof w);
    memcpy(o, origin, sizeof o);
    for (int j = 0; j < d->n_ports; j++)
        if (D->port_mode[2 * j + 1] == MOTION) {
            idx_t k = D->port_node[j];
            memcpy(Rr, RN_p + 9 * k, sizeof Rr);
            for (int i = 0; i < 3; i++) /* w = R W */
                w[i] = Rr[3 * i] * zN_p[6 * k + 3] + Rr[3 * i + 1] * zN_p[6 * k + 4] + Rr[3 * i + 2] * zN_p[6 * k + 5];
            break;
        }
    for (int j = 0; j < d->n_ports; j++)
        if (D->port_mode[2 * j] == MOTION) {
            idx_t k = D->port_node[j];
            for (int i = 0; i < 3; i++) {
                c_ref[i] = st->xN[3 * k + i];
                c_new[i] = xN_p[3 * k + i];
                v_lin[i] = zN_p[6 * k + i];
                o[i] = c_new[i];
            }
            break;
        }
    for (int q = 0; q < 2; q++) { /* place(X) = c_new + R (X - c_ref) */
        double *X = q == 0 ? st->xN : st->x0, *Rq = q == 0 ? st->RN : st->R0;
        int n = q == 0 ? N : E;
        for (int k = 0; k < n; k++) {
            double y[3] = {X[3 * k] - c_ref[0], X[3 * k + 1] - c_ref[1], X[3 * k + 2] - c_ref[2]};
            for (int i = 0; i < 3; i++)
                X[3 * k + i] = c_new[i] + Rr[3 * i] * y[0] + Rr[3 * i + 1] * y[1] + Rr[3 * i + 2] * y[2];
            memcpy(Rq + 9 * k, Rr, sizeof Rr);
        }
    }
    if (port_displacements) {
        for (int j = 0; j < d->n_ports; j++)
            for (int i = 0; i < 3; i++)
                st->xN[3 * D->port_node[j] + i] += port_displacements[3 * j + i];
        status = relax(b, port_displacements, last);
        if (status != 0)
            goto done;
    }
    /* the rigid velocity field: node and CM rates, the CM velocities */
    double *yd = st->yd;
    memset(yd, 0, sizeof(double) * (size_t)ny);
    memset(st->v, 0, sizeof(double) * (size_t)(E * nv));
    for (int q = 0; q < 2; q++) {
        const double *X = q == 0 ? st->xN : st->x0, *Rq = q == 0 ? st->RN : st->R0;
        int n = q == 0 ? N : E;
        for (int k = 0; k < n; k++) {
            double *z = q == 0 ? yd + 6 * k : yd + 6 * N + k * (6 + nm);
            const double *x = X + 3 * k, *Rk = Rq + 9 * k;
            double r[3] = {x[0] - o[0], x[1] - o[1], x[2] - o[2]};
            z[0] = v_lin[0] + (w[1] * r[2] - w[2] * r[1]);
            z[1] = v_lin[1] + (w[2] * r[0] - w[0] * r[2]);
            z[2] = v_lin[2] + (w[0] * r[1] - w[1] * r[0]);
            for (int i = 0; i < 3; i++) /* R^T w */
                z[3 + i] = Rk[i] * w[0] + Rk[3 + i] * w[1] + Rk[6 + i] * w[2];
            if (q == 1)
                memcpy(st->v + (size_t)k * nv, z, 6 * sizeof(double));
        }
    }
    /* r_bar = q_bar_dot of the rigid field (eq. 91; zero unless ports were displaced): equations.kinematics */
    for (int e = 0; e < E; e++) {
        const idx_t *cfg = D->cfg_map + (size_t)e * d->nc;
        const double *R0 = st->R0 + 9 * e, *x0 = st->x0 + 3 * e;
        const double *x0d = yd + cfg[0], *W0 = yd + cfg[3];
        double *r = st->v + (size_t)e * nv + 6;
        for (int q = 0; q < d->nb; q++) {
            idx_t k = D->se_nodes[(size_t)e * d->nb + q];
            const double *xP = st->xN + 3 * k, *RP = st->RN + 9 * k;
            const double *xPd = yd + cfg[6 + nm + 6 * q], *WP = yd + cfg[9 + nm + 6 * q];
            double rho[3], u[3], Q[9], c[3], H[9];
            for (int i = 0; i < 3; i++) {
                rho[i] = R0[i] * (xP[0] - x0[0]) + R0[3 + i] * (xP[1] - x0[1]) + R0[6 + i] * (xP[2] - x0[2]);
                u[i] = R0[i] * (xPd[0] - x0d[0]) + R0[3 + i] * (xPd[1] - x0d[1]) + R0[6 + i] * (xPd[2] - x0d[2]);
                for (int j = 0; j < 3; j++)
                    Q[3 * i + j] = R0[i] * RP[j] + R0[3 + i] * RP[3 + j] + R0[6 + i] * RP[6 + j];
            }
            for (int i = 0; i < 3; i++) /* c = W_P - Q^T W0 */
                c[i] = WP[i] - (Q[i] * W0[0] + Q[3 + i] * W0[1] + Q[6 + i] * W0[2]);
            double tr = Q[0] + Q[4] + Q[8];
            for (int i = 0; i < 3; i++) /* H = (tr Q I - Q^T) / 2 */
                for (int j = 0; j < 3; j++)
                    H[3 * i + j] = 0.5 * ((i == j ? tr : 0.0) - Q[3 * j + i]);
            double *dr = r + 6 * q;
            dr[0] = u[0] + (rho[1] * W0[2] - rho[2] * W0[1]);
            dr[1] = u[1] + (rho[2] * W0[0] - rho[0] * W0[2]);
            dr[2] = u[2] + (rho[0] * W0[1] - rho[1] * W0[0]);
            for (int i = 0; i < 3; i++)
                dr[3 + i] = H[3 * i] * c[0] + H[3 * i + 1] * c[1] + H[3 * i + 2] * c[2];
        }
        for (int i = 0; i < nm; i++) /* modal rates: eta_dot (zero here), the last nm entries of r_bar */
            r[6 * d->nb + i] = yd[cfg[6 + i]];
    }
    double *cfg_rates = p; /* (p is free until the residual below) */
    memcpy(cfg_rates, yd, sizeof(double) * (size_t)n_cfg);
    memcpy(st->fN, b->in.f_in, sizeof(double) * 3 * (size_t)N);
    memcpy(st->tN, b->in.t_in, sizeof(double) * 3 * (size_t)N);
    /* consistent ydot_0: a backward-Euler micro-step from the initial state (predictor: the rates as they are) */
    memcpy(st->yd_prev, yd, sizeof(double) * (size_t)ny);
    memcpy(st->yd_prev2, yd, sizeof(double) * (size_t)ny);
    memcpy(st->a, yd, sizeof(double) * (size_t)ny);
    b->lu.meta[0] = 0.0;
    ffrf_body_get_state(b, saved);
    double am = b->am, af = b->af, gamma = b->gamma;
    b->am = b->af = b->gamma = 1.0;
    if (kind == FFRF_GIVEN) /* the caller's inputs at t0 + delta, nodes without motion inputs keeping their frames */
        given_inputs(b, next);
    else
        ffrf_extrapolated_inputs(b, t0 + FFRF_MICRO_STEP, t0);
    int step = ffrf_step(b, FFRF_MICRO_STEP, 0);
    *last = b->lu.meta[1];
    b->am = am;
    b->af = af;
    b->gamma = gamma;
    memcpy(yd0, st->yd, sizeof(double) * (size_t)ny);
    ffrf_body_set_state(b, saved, state_size);
    if (step != FFRF_OK) {
        status = step;
        goto done;
    }
    /* its configuration rates are the velocities at t0 + delta: keep its velocity rates, the exact
     * configuration rates at t0 */
    memcpy(yd0, cfg_rates, sizeof(double) * (size_t)n_cfg);
    memcpy(st->yd, yd0, sizeof(double) * (size_t)ny);
    memcpy(st->yd_prev, yd0, sizeof(double) * (size_t)ny);
    memcpy(st->yd_prev2, yd0, sizeof(double) * (size_t)ny);
    memcpy(st->a, yd0, sizeof(double) * (size_t)ny);
    if (kind == FFRF_GIVEN)
        inputs_io(b, at_t0, 1);
    else
        ffrf_extrapolated_inputs(b, t0, t0);
    port_loads(b, p, R, theta);
    status = 0;
done:
    free(at_t0);
    free(saved);
    free(yd0);
    free(p);
    free(R);
    free(theta);
    return status;
}

