/* Many steps in one call (the C twin of simulate.scene_inputs and runtime/input_rule.py `inputs` with BodySystem.step): a
 * standalone run whose inputs are known functions of time (a scene's drives and loads) or an FMU's
 * communication step (inputs extrapolated from the point values, the inputs set at the communication point) takes its
 * steps here, the inputs evaluated and the output rows recorded without returning to the caller.
 * The numpy twins: simulate.scene_inputs, runtime/input_rule.py inputs, BodySystem._read_inputs,
 * simulate.record (BodySystem.port_array, energies). */
#include <math.h>
#include <string.h>

#include "advance.h"
#include "so3.h"
#include "step.h"
#include "accel.h"

/* No fused multiply-adds: the results must match the numpy path (which never contracts) to round-off. Clang (and zig cc,
 * which targets the host CPU) contracts within expressions by default; GCC in ISO C mode does not. */
#if defined(__clang__)
#pragma STDC FP_CONTRACT OFF
#endif

/* (s, ds/dt) of a time function into out (runtime/drives.py evaluate; kind codes drives.CODES). */
static void time_function(idx_t kind, const double *prm, double t, double out[2])
{
    if (kind == 0) { /* constant */
        out[0] = prm[0];
        out[1] = 0.0;
    } else if (kind == 1) { /* haug_spinup (omega, T) */
        double w = prm[0], T = prm[1];
        if (t < T) {
            double tau = t / T;
            double two_pi = 2.0 * FFRF_PI;
            out[0] = w * T * (tau * tau / 2.0 + (cos(two_pi * tau) - 1.0) / (two_pi * two_pi));
            out[1] = w * (tau - sin(two_pi * tau) / two_pi);
        } else {
            out[0] = w * T * (t / T - 0.5);
            out[1] = w;
        }
    } else if (kind == 2) { /* ramp (rate, t_start) */
        double dt = t - prm[1];
        if (dt > 0.0) {
            out[0] = prm[0] * dt;
            out[1] = prm[0];
        } else {
            out[0] = 0.0;
            out[1] = 0.0;
        }
    } else if (kind == 3) { /* window (value, t_start, t_end) */
        out[0] = prm[1] <= t && t < prm[2] ? prm[0] : 0.0;
        out[1] = 0.0;
    } else if (kind == 4) { /* sine (amplitude, frequency_hz, phase) */
        double w = 2.0 * FFRF_PI * prm[1];
        out[0] = prm[0] * sin(w * t + prm[2]);
        out[1] = prm[0] * w * cos(w * t + prm[2]);
    } else { /* bump (value, t_start, duration): value sin^4(pi tau) for tau in [0, 1) */
        double tau = (t - prm[1]) / prm[2];
        if (tau >= 0.0 && tau < 1.0) {
            double sn = sin(FFRF_PI * tau), cs = cos(FFRF_PI * tau);
            out[0] = prm[0] * sn * sn * sn * sn;
            out[1] = 4.0 * prm[0] * (FFRF_PI / prm[2]) * sn * sn * sn * cs;
        } else {
            out[0] = 0.0;
            out[1] = 0.0;
        }
    }
}

/* The inputs of a step where no port prescribes anything: the current frames (`BodySystem._read_inputs`
 * where there is no motion input), zero rates, zero loads. The input functions overwrite what the ports set. */
static void no_inputs(ffrf_body *b)
{
    const int N = b->dims.N;
    memcpy(b->in.xN_p, b->state.xN, (size_t)3 * N * sizeof(double));
    memcpy(b->in.RN_p, b->state.RN, (size_t)9 * N * sizeof(double));
    for (int i = 0; i < 6 * N; i++)
        b->in.zN_p[i] = 0.0;
    for (int i = 0; i < 3 * N; i++) {
        b->in.f_in[i] = 0.0;
        b->in.t_in[i] = 0.0;
    }
}

/* A port's rotation Rd and world angular velocity wd at the step's end: a motion-driven rotation into
 * the node's prescribed frame RN_p[k] and body-axes rate zN_p[k, 3:] = Rd^T wd, else into the compliant
 * spring's input slot s (R_in, w_in). Shared by the scene's schedule and the point values. */
static void put_rotation(ffrf_body *b, int motion, idx_t k, idx_t s, const double Rd[9], const double wd[3])
{
    if (motion) {
        memcpy(b->in.RN_p + 9 * k, Rd, 9 * sizeof(double));
        for (int i = 0; i < 3; i++)
            b->in.zN_p[6 * k + 3 + i] = wd[0] * Rd[i] + wd[1] * Rd[3 + i] + wd[2] * Rd[6 + i];
    } else {
        memcpy(b->springs.R_in + 9 * s, Rd, 9 * sizeof(double));
        memcpy(b->springs.w_in + 3 * s, wd, 3 * sizeof(double));
    }
}

/* A port's position r and world velocity v at the step's end: a motion-driven translation into the
 * node's prescribed position xN_p[k] and rate zN_p[k, :3], else into the compliant spring's input slot s
 * (r_in, v_in). Shared by the scene's schedule and the point values, as put_rotation. */
static void put_translation(ffrf_body *b, int motion, idx_t k, idx_t s, const double r[3], const double v[3])
{
    for (int i = 0; i < 3; i++) {
        if (motion) {
            b->in.xN_p[3 * k + i] = r[i];
            b->in.zN_p[6 * k + i] = v[i];
        } else {
            b->springs.r_in[3 * s + i] = r[i];
            b->springs.v_in[3 * s + i] = v[i];
        }
    }
}

/* The inputs of a step at time t from a scene's schedule (simulate.scene_schedule, after the ports'
 * (node, mode, spring) = runtime/input_rule.py port_codes): what simulate.scene_inputs gives and
 * BodySystem._read_inputs reads. Parts: 0 force, 1 motion, 2 compliant. A load window acts with its
 * mean over the step (t - h, t] (drives.window_share: the impulse is exact for any step). */
void ffrf_scheduled_inputs(ffrf_body *b, double t, double h)
{
    const ffrf_data *D = &b->data;
    const ffrf_schedule *sc = &b->schedule;
    double *f_in = b->in.f_in, *t_in = b->in.t_in;
    double sv[2] = {0.0, 0.0}, th[3] = {0.0, 0.0, 0.0}, Rd[9] = {0.0}, wd[3] = {0.0, 0.0, 0.0};
    no_inputs(b);
    for (int j = 0; j < b->dims.n_ports; j++) {
        idx_t k = D->port_node[j], s = D->port_spring[j];
        const idx_t *mode = D->port_mode + 2 * j, *kind = sc->kind + 2 * j;
        const double *r0 = sc->r0 + 3 * j, *axis = sc->axis + 6 * j, *prm = sc->prm + 6 * j;
        if (mode[0] != 0) { /* motion or the far end of a spring: r = r0 + u e, v = du e */
            sv[0] = 0.0;
            sv[1] = 0.0;
            if (kind[0] >= 0)
                time_function(kind[0], prm, t, sv);
            double r[3], vv[3];
            for (int i = 0; i < 3; i++) {
                r[i] = r0[i] + sv[0] * axis[i];
                vv[i] = sv[1] * axis[i];
            }
            put_translation(b, mode[0] == 1, k, s, r, vv);
        }
        if (mode[1] != 0) { /* R = exp(phi a), w = dphi a (world) */
            sv[0] = 0.0;
            sv[1] = 0.0;
            if (kind[1] >= 0)
                time_function(kind[1], prm + 3, t, sv);
            for (int i = 0; i < 3; i++) {
                th[i] = sv[0] * axis[3 + i];
                wd[i] = sv[1] * axis[3 + i];
            }
            ffrf_expm(th, Rd);
            put_rotation(b, mode[1] == 1, k, s, Rd, wd);
        }
    }
    for (int ld = 0; ld < b->dims.n_loads; ld++) {
        const double *win = sc->load_window + 2 * ld, *fm = sc->load_fm + 6 * ld;
        double share = (fmin(t, win[1]) - fmax(t - h, win[0])) / h;
        if (share > 0.0) {
            idx_t j = sc->load_port[ld];
            idx_t k = D->port_node[j];
            const idx_t *mode = D->port_mode + 2 * j;
            for (int i = 0; i < 3; i++) {
                if (mode[0] == 0)
                    f_in[3 * k + i] += share * fm[i];
                if (mode[1] == 0)
                    t_in[3 * k + i] += share * fm[3 + i];
            }
        }
    }
}

/* The inputs of a step at time t extrapolated from the point values (runtime/input_rule.py `extrapolate`, read by
 * BodySystem._read_inputs): b->point_values one row per port, columns input_rule.COLUMNS (r 0, v 3, a 6, R 9, w 18,
 * dw 21, f 24, t 27); port modes 0 force, 1 motion, 2 compliant. runtime/input_rule.py `inputs`. */
void ffrf_extrapolated_inputs(ffrf_body *b, double t, double t_c)
{
    const ffrf_data *D = &b->data;
    double *f_in = b->in.f_in, *t_in = b->in.t_in;
    double th[3], E[9], Rd[9], wd[3];
    no_inputs(b);
    double dt = t - t_c;
    double half = 0.5 * dt * dt;
    for (int j = 0; j < b->dims.n_ports; j++) {
        idx_t k = D->port_node[j], s = D->port_spring[j];
        const idx_t *mode = D->port_mode + 2 * j;
        const double *row = b->point_values + (size_t)FFRF_POINT_WIDTH * j;
        if (mode[0] == 0) {
            for (int i = 0; i < 3; i++)
                f_in[3 * k + i] = row[24 + i];
        } else {
            double r[3], vv[3];
            for (int i = 0; i < 3; i++) {
                r[i] = row[i] + row[3 + i] * dt + half * row[6 + i];
                vv[i] = row[3 + i] + dt * row[6 + i];
            }
            put_translation(b, mode[0] == 1, k, s, r, vv);
        }
        if (mode[1] == 0) {
            for (int i = 0; i < 3; i++)
                t_in[3 * k + i] = row[27 + i];
        } else {
            for (int i = 0; i < 3; i++) {
                th[i] = row[18 + i] * dt + half * row[21 + i];
                wd[i] = row[18 + i] + dt * row[21 + i];
            }
            ffrf_expm(th, E);
            for (int i = 0; i < 3; i++)
                for (int m = 0; m < 3; m++)
                    Rd[3 * i + m] = E[3 * i] * row[9 + m] + E[3 * i + 1] * row[12 + m] + E[3 * i + 2] * row[15 + m];
            put_rotation(b, mode[1] == 1, k, s, Rd, wd);
        }
    }
}

/* One row of simulate.record: per port r, R (row-major), v, w = R W, f, t and the node's true accelerations
 * a, dw (accel.c) (BodySystem.port_array); the
 * energies kinetic_rigid, kinetic_elastic, strain, work_external (BodySystem.energies); the iterations of
 * the last step. BodySystem.output_row. */
void ffrf_record(const ffrf_body *b, double *row)
{
    const ffrf_data *D = &b->data;
    const ffrf_dims *d = &b->dims;
    const ffrf_state *st = &b->state;
    const double *xN = st->xN, *RN = st->RN, *x0 = st->x0, *R0 = st->R0, *eta = st->eta, *v = st->v, *yd = st->yd;
    const int n = d->n, nb = d->nb, nm = d->nm, nv = d->nv, n_vk = d->n_vk, n_w2 = d->n_w2;
    int col = 0;
    for (int j = 0; j < d->n_ports; j++) {
        idx_t k = D->port_node[j];
        const double *RNk = RN + 9 * k;
        for (int i = 0; i < 3; i++) {
            row[col + i] = xN[3 * k + i];
            row[col + 12 + i] = yd[6 * k + i];
            row[col + 15 + i] = RNk[3 * i] * yd[6 * k + 3] + RNk[3 * i + 1] * yd[6 * k + 4] + RNk[3 * i + 2] * yd[6 * k + 5];
            row[col + 18 + i] = st->fN[3 * k + i];
            row[col + 21 + i] = st->tN[3 * k + i];
            for (int m = 0; m < 3; m++)
                row[col + 3 + 3 * i + m] = RNk[3 * i + m];
        }
        ffrf_port_accelerations(b, j, row + col + 24, row + col + 27);
        col += FFRF_OUTPUT_WIDTH;
    }
    double *q = b->work.q_rec, Jq[9];
    double kr = 0.0, ke = 0.0, sn = 0.0;
    for (int e = 0; e < d->E; e++) {
        const double *R0e = R0 + 9 * e, *x0e = x0 + 3 * e, *ve = v + (size_t)e * nv;
        const double *Ke = D->K + (size_t)e * n * n, *Me = D->M + (size_t)e * n * n, *Je = D->J0 + 9 * e;
        for (int pp = 0; pp < nb; pp++) { /* q_bar (89): d_P = R0^T (x_P - x0) - X_P, alpha_P = vect(R0^T R_P) */
            idx_t P = D->se_nodes[(size_t)e * nb + pp];
            const double *RP = RN + 9 * P;
            double Q[9] = {0.0};
            for (int i = 0; i < 3; i++) {
                double s = 0.0;
                for (int m = 0; m < 3; m++) {
                    s += R0e[3 * m + i] * (xN[3 * P + m] - x0e[m]);
                    for (int l = 0; l < 3; l++)
                        Q[3 * i + l] += R0e[3 * m + i] * RP[3 * m + l];
                }
                q[6 * pp + i] = s - D->X_B[((size_t)e * nb + pp) * 3 + i];
            }
            q[6 * pp + 3] = 0.5 * (Q[7] - Q[5]);
            q[6 * pp + 4] = 0.5 * (Q[2] - Q[6]);
            q[6 * pp + 5] = 0.5 * (Q[3] - Q[1]);
        }
        for (int i = 0; i < nm; i++)
            q[6 * nb + i] = eta[(size_t)e * nm + i];
        for (int i = 0; i < 3; i++) {
            kr += 0.5 * D->mass[e] * ve[i] * ve[i];
            for (int m = 0; m < 3; m++)
                kr += 0.5 * ve[3 + i] * Je[3 * i + m] * ve[3 + m];
        }
        for (int i = 0; i < n; i++)
            for (int m = 0; m < n; m++) {
                ke += 0.5 * ve[6 + i] * Me[(size_t)i * n + m] * ve[6 + m];
                sn += 0.5 * q[i] * Ke[(size_t)i * n + m] * q[m];
            }
        for (int kk = 0; kk < n_vk; kk++) { /* V2 = e.sigma + sigma.sigma / 2 (stiffening.von_karman) */
            const double *a_k = D->vk_a + ((size_t)e * n_vk + kk) * n, *B_k = D->vk_B + ((size_t)e * n_vk + kk) * n * n;
            double ek = 0.0, sk = 0.0;
            for (int i = 0; i < n; i++) {
                ek += a_k[i] * q[i];
                for (int m = 0; m < n; m++)
                    sk += 0.5 * q[i] * B_k[(size_t)i * n + m] * q[m];
            }
            sn += (ek + 0.5 * sk) * sk;
        }
        if (D->stiff) { /* 1/2 Omega0^T (W1 q [+ q W2 q]) Omega0 (stiffening.deformed_inertia) */
            const double *W1e = D->W1 + (size_t)e * d->n_w1 * 9, *W2e = D->W2 + (size_t)e * n_w2 * n_w2 * 9;
            for (int a = 0; a < 3; a++)
                for (int c = 0; c < 3; c++) {
                    double s = 0.0;
                    for (int i = 0; i < n; i++) {
                        s += q[i] * W1e[(size_t)i * 9 + 3 * a + c];
                        for (int m = 0; m < n_w2; m++)
                            s += q[i] * W2e[((size_t)i * n_w2 + m) * 9 + 3 * a + c] * q[m];
                    }
                    Jq[3 * a + c] = s;
                }
            for (int a = 0; a < 3; a++)
                for (int c = 0; c < 3; c++)
                    kr += 0.5 * ve[3 + a] * Jq[3 * a + c] * ve[3 + c];
        }
    }
    row[col] = kr;
    row[col + 1] = ke;
    row[col + 2] = sn;
    row[col + 3] = st->energy[0];
    row[col + 4] = st->iterations;
}

void ffrf_body_record(const ffrf_body *b, double *row)
{
    ffrf_record(b, row);
}

/* n steps of h from the body's time (`ffrf_step` each), their inputs by kind: FFRF_GIVEN as the caller
 * set them in b->in (BodySystem.step, n = 1), FFRF_SCHEDULED from the scene's schedule (every step's row
 * recorded into rows[k] and its time into times[k], simulate.record's layout), FFRF_EXTRAPOLATED extrapolated
 * from the point values at t_c (an FMU's communication step; the last step's row into rows). The
 * time advances by one addition of h per step (the clock of `step`); b->state.iterations
 * holds the last completed step's iterations. Returns the steps completed; *status the status of the
 * failed step (FFRF_OK if none; FFRF_BAD_STEP for h not positive and finite, nothing stepped), *worst
 * the most Newton iterations of a step. A failed step leaves the state at the last completed one, rows
 * untouched. */
int ffrf_body_advance(ffrf_body *b, int kind, int n, double h, double t_c, double *rows, double *times, int *status,
                      int *worst)
{
    const size_t row_size = (size_t)FFRF_OUTPUT_WIDTH * b->dims.n_ports + FFRF_N_ENERGIES + 1;
    *status = FFRF_OK;
    *worst = 0;
    if (!(h > 0.0 && isfinite(h))) {
        *status = FFRF_BAD_STEP;
        return 0;
    }
    for (int k = 0; k < n; k++) {
        double t1 = b->state.t + h;
        if (kind == FFRF_SCHEDULED)
            ffrf_scheduled_inputs(b, t1, h);
        else if (kind == FFRF_EXTRAPOLATED)
            ffrf_extrapolated_inputs(b, t1, t_c);
        int st = ffrf_step(b, h, b->state.iterations);
        if (st != FFRF_OK) {
            *status = st;
            return k;
        }
        if (b->state.iterations > *worst)
            *worst = b->state.iterations;
        b->state.t = t1;
        if (kind == FFRF_SCHEDULED) {
            times[k] = t1;
            ffrf_record(b, rows + row_size * k);
        }
    }
    if (kind == FFRF_EXTRAPOLATED && n > 0)
        ffrf_record(b, rows);
    return n;
}
