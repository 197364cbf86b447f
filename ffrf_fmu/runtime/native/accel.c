/* The true accelerations of a port's node at the end of a step: the columns a and dw of the output row
 * (ffrf_record), the C twin of runtime/accelerations.py, whose docstring has the equations: the time
 * derivative of the node's velocity (geradin eq. 91) along the solution, with the rates of the velocity
 * field the step solved for (v0dot, Omega0dot, r_bar_dot of the node's first superelement) and q_bar''
 * from the time derivative of the kinematic row (79). Not the integrator's acceleration-like variable a. */
#include <string.h>

#include "accel.h"
#include "so3.h"
#include "lu.h"

#if defined(__clang__)
#pragma STDC FP_CONTRACT OFF
#endif

/* The LU factors of each superelement's M_bar (for q_bar'' with the Coriolis part) and its inverse (factor.c's
 * elimination of the velocity unknowns): once, at creation. Returns 0, or -1 when an M_bar is singular. */
int ffrf_mass_factors(ffrf_body *b)
{
    const int n = b->dims.n;
    for (int e = 0; e < b->dims.E; e++) {
        double *luT = b->work.M_luT + (size_t)e * n * n, *inv = b->work.M_inv + (size_t)e * n * n;
        memcpy(luT, b->data.M + (size_t)e * n * n, (size_t)n * n * sizeof(double)); /* symmetric: M^T = M */
        if (ffrf_lu_factor(luT, b->work.M_piv + (size_t)e * n, n))
            return -1;
        for (int j = 0; j < n; j++) { /* column j of M_bar^-1 */
            double *col = inv + (size_t)j * n;
            memset(col, 0, (size_t)n * sizeof(double));
            col[j] = 1.0;
            ffrf_lu_solve(luT, b->work.M_piv + (size_t)e * n, col, n);
        }
    }
    return 0;
}

static void mat_vec(const double A[9], const double x[3], double out[3])
{
    for (int i = 0; i < 3; i++)
        out[i] = A[3 * i] * x[0] + A[3 * i + 1] * x[1] + A[3 * i + 2] * x[2];
}

static void mat_t_vec(const double A[9], const double x[3], double out[3])
{
    for (int i = 0; i < 3; i++)
        out[i] = A[i] * x[0] + A[3 + i] * x[1] + A[6 + i] * x[2];
}

/* (Q = R0^T R_P, H(Q) = (tr Q I - Q^T) / 2, rho = R0^T (x_P - x0)) of node P of superelement e. */
static void node_frame(const ffrf_body *b, int e, idx_t P, double Q[9], double H[9], double rho[3])
{
    const double *R0 = b->state.R0 + 9 * e, *RP = b->state.RN + 9 * P, *x0 = b->state.x0 + 3 * e;
    const double *xP = b->state.xN + 3 * P;
    double dx[3] = {xP[0] - x0[0], xP[1] - x0[1], xP[2] - x0[2]};
    mat_t_vec(R0, dx, rho);
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            Q[3 * i + j] = R0[i] * RP[j] + R0[3 + i] * RP[3 + j] + R0[6 + i] * RP[6 + j];
    double tr = Q[0] + Q[4] + Q[8];
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            H[3 * i + j] = 0.5 * ((i == j ? tr : 0.0) - Q[3 * j + i]);
}

void ffrf_port_accelerations(const ffrf_body *b, int port, double a[3], double dw[3])
{
    const ffrf_dims *d = &b->dims;
    const ffrf_data *D = &b->data;
    const int n = d->n, nb = d->nb, nm = d->nm;
    const idx_t k = D->port_node[port];
    int e = 0, p = 0;
    for (int i = 0; i < d->E * nb; i++) /* the node's first superelement (accelerations.port_owners) */
        if (D->se_nodes[i] == k) {
            e = i / nb;
            p = i % nb;
            break;
        }
    const double *yd = b->state.yd, *R0 = b->state.R0 + 9 * e;
    const idx_t *cfg = D->cfg_map + (size_t)e * d->nc, *vel = D->vel_map + (size_t)e * d->nv;
    double x0dot[3], W0[3], v0dot[3], Omdot[3];
    for (int i = 0; i < 3; i++) {
        x0dot[i] = yd[cfg[i]];
        W0[i] = yd[cfg[3 + i]];
        v0dot[i] = yd[vel[i]];
        Omdot[i] = yd[vel[3 + i]];
    }
    /* q_bar and q_bar' (89), (91) of every boundary node, then the modes */
    double *q = b->work.acc, *qd = q + n, *qdd = q + 2 * n;
    double Q[9], H[9], rho[3], u[3], c[3], t3[3], t4[3];
    for (int pp = 0; pp < nb; pp++) {
        idx_t P = D->se_nodes[(size_t)e * nb + pp];
        node_frame(b, e, P, Q, H, rho);
        double dx[3];
        for (int i = 0; i < 3; i++)
            dx[i] = yd[cfg[6 + nm + 6 * pp + i]] - x0dot[i];
        mat_t_vec(R0, dx, u);
        ffrf_cross(rho, W0, t3);
        mat_t_vec(Q, W0, t4);
        for (int i = 0; i < 3; i++) {
            q[6 * pp + i] = rho[i] - D->X_B[((size_t)e * nb + pp) * 3 + i];
            qd[6 * pp + i] = u[i] + t3[i];
            c[i] = yd[cfg[9 + nm + 6 * pp + i]] - t4[i];
        }
        q[6 * pp + 3] = 0.5 * (Q[7] - Q[5]);
        q[6 * pp + 4] = 0.5 * (Q[2] - Q[6]);
        q[6 * pp + 5] = 0.5 * (Q[3] - Q[1]);
        mat_vec(H, c, qd + 6 * pp + 3);
    }
    for (int i = 0; i < nm; i++) {
        q[6 * nb + i] = b->state.eta[(size_t)e * nm + i];
        qd[6 * nb + i] = yd[cfg[6 + i]];
    }
    /* q_bar'' = r_bar_dot [- M^-1 (G(Omega0dot) q_bar + G(W0) q_bar')] */
    for (int i = 0; i < n; i++)
        qdd[i] = 0.0;
    if (D->gyro & FFRF_CORIOLIS) {
        const int ng = d->n_g;
        for (int kk = 0; kk < 3; kk++) {
            const double *Gk = D->G + ((size_t)e * 3 + kk) * ng * ng;
            for (int i = 0; i < n; i++) {
                double s = 0.0;
                for (int j = 0; j < n; j++)
                    s += Gk[(size_t)i * ng + j] * (Omdot[kk] * q[j] + W0[kk] * qd[j]);
                qdd[i] += s;
            }
        }
        ffrf_lu_solve(b->work.M_luT + (size_t)e * n * n, b->work.M_piv + (size_t)e * n, qdd, n);
    }
    for (int i = 0; i < n; i++)
        qdd[i] = yd[vel[6 + i]] - qdd[i];
    /* x_P'' = v0dot + R0 [Omega0dot x rho + W0 x (W0 x rho) + 2 W0 x d_P' + d_P''] */
    node_frame(b, e, k, Q, H, rho);
    const double *dP = qd + 6 * p, *ddP = qdd + 6 * p;
    double s[3], t1[3], t2[3];
    ffrf_cross(Omdot, rho, t1);
    ffrf_cross(W0, rho, t3);
    ffrf_cross(W0, t3, t2);
    ffrf_cross(W0, dP, t4);
    for (int i = 0; i < 3; i++)
        s[i] = t1[i] + t2[i] + 2.0 * t4[i] + ddP[i];
    mat_vec(R0, s, t1);
    for (int i = 0; i < 3; i++)
        a[i] = v0dot[i] + t1[i];
    /* dw_P = R0 Omega0dot + R_P (W_P x c + c'), c = W_P - Q^T W0, c' = H^-1 (alpha'' - H' c),
     * H' c = -c (alpha . c) + c x (Q^T c) / 2 */
    const double *WP = yd + 6 * k + 3;
    double alpha[3] = {0.5 * (Q[7] - Q[5]), 0.5 * (Q[2] - Q[6]), 0.5 * (Q[3] - Q[1])}, Hinv[9];
    mat_t_vec(Q, W0, t4);
    for (int i = 0; i < 3; i++)
        c[i] = WP[i] - t4[i];
    double ac = alpha[0] * c[0] + alpha[1] * c[1] + alpha[2] * c[2];
    mat_t_vec(Q, c, t4);
    ffrf_cross(c, t4, t3);
    for (int i = 0; i < 3; i++)
        t1[i] = ddP[3 + i] - (-c[i] * ac + 0.5 * t3[i]);
    ffrf_inv3(H, Hinv);
    mat_vec(Hinv, t1, t2); /* c' */
    ffrf_cross(WP, c, t3);
    for (int i = 0; i < 3; i++)
        t3[i] += t2[i];
    mat_vec(b->state.RN + 9 * k, t3, t1);
    mat_vec(R0, Omdot, t2);
    for (int i = 0; i < 3; i++)
        dw[i] = t2[i] + t1[i];
}
