/* The initial state of a body FMU: the runtime's (runtime/native/initial.c `ffrf_body_initialize`, BodySystem.initialize
 * on the C runtime's body) from the point values at t0 and the FMU's parameters, with the FMU's words for its
 * failures; the start state made at build taken at t0 (`fmu_start_body`). */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "body.h"
#include "initial.h"
#include "initialize.h"
#include "resource.h" /* PART_MOTION, PART_FORCE: the port modes */

int fmu_initialize_body(ffrf_body *b, double t0, const double velocity[3], const double angular_velocity[3],
                        const double origin[3], const double *port_displacements, const char *const *port_names,
                        char *err, size_t err_len)
{
    double last = 0.0;
    int status = ffrf_body_initialize(b, t0, velocity, angular_velocity, origin, port_displacements, FFRF_EXTRAPOLATED,
                                      NULL, &last);
    if (status == 0)
        return 0;
    if (status == FFRF_INIT_NO_MEMORY) {
        snprintf(err, err_len, "out of memory");
        return -1;
    }
    if (status > 0) {
        snprintf(err, err_len, "%s (the consistent initial rates: a backward-Euler step of %g s)",
                 ffrf_status_text(status), FFRF_MICRO_STEP);
        return -1;
    }
    const int n_ports = b->dims.n_ports;
    const ffrf_data *D = &b->data;
    char names[512] = "";
    /* the ports with a displacement parameter, sorted by name as Python's sorted() */
    int used[64] = {0};
    size_t k = (size_t)snprintf(names, sizeof names, "[");
    for (int round = 0; round < n_ports && round < 64; round++) {
        int best = -1;
        for (int j = 0; j < n_ports && j < 64; j++)
            if (!used[j] && D->port_mode[2 * j] == PART_FORCE &&
                (best < 0 || strcmp(port_names[j], port_names[best]) < 0))
                best = j;
        if (best < 0)
            break;
        used[best] = 1;
        k += (size_t)snprintf(names + k, k < sizeof names ? sizeof names - k : 0, "%s'%s'", k > 1 ? ", " : "",
                              port_names[best]);
    }
    if (k < sizeof names)
        snprintf(names + k, sizeof names - k, "]");
    snprintf(err, err_len, "initial port displacements %s: no static equilibrium of the deformed body found (%d Newton "
             "iterations, last correction %.3g); smaller displacements, or ports whose displacements the body can "
             "hold", names, FFRF_RELAX_MAX_ITER, last);
    return -1;
}

/* The start state made at build (runtime/start.py: the scene's static equilibrium or steady spin), taken by a
 * body just initialized at the inputs of t0 (fmu_initialize_body): its motion-driven ports must be where the
 * start has them (positions, rotations and their rates to START_MOTION_TOL relative, `mismatch`), then the
 * START_FIELDS are copied in and the port loads at t0 computed from the state (`adopt`). start: the
 * START_FIELDS (xN, RN, x0, R0, eta, v, yd, yd_prev, yd_prev2, a) of `count` doubles; 0, or -1 with err set. */
#define START_MOTION_TOL 1e-9 /* runtime/start.py MOTION_TOL (tests/test_facts.py) */
int fmu_start_body(ffrf_body *b, double t0, const double *start, size_t count, const char *const *port_names,
                   char *err, size_t err_len)
{
    const ffrf_dims *d = &b->dims;
    const ffrf_data *D = &b->data;
    ffrf_state *st = &b->state;
    const int N = d->N, E = d->E, ny = d->ny;
    double *dst[10] = {st->xN, st->RN, st->x0, st->R0, st->eta, st->v, st->yd, st->yd_prev, st->yd_prev2, st->a};
    const size_t sizes[10] = {3 * (size_t)N, 9 * (size_t)N, 3 * (size_t)E, 9 * (size_t)E, (size_t)E * (size_t)d->nm,
                              (size_t)E * (size_t)d->nv, (size_t)ny, (size_t)ny, (size_t)ny, (size_t)ny};
    size_t total = 0;
    for (int q = 0; q < 10; q++)
        total += sizes[q];
    if (count != total) {
        snprintf(err, err_len, "the start state has %zu values, this body needs %zu (a damaged resource)", count, total);
        return -1;
    }
    const double *s_xN = start, *s_RN = start + sizes[0], *s_yd = start + total - 4 * (size_t)ny;
    for (int j = 0; j < d->n_ports; j++) {
        idx_t k = D->port_node[j];
        for (int part = 0; part < 2; part++) {
            if (D->port_mode[2 * j + part] != PART_MOTION)
                continue;
            /* translation: r (xN) and v (node rates 0..2); rotation: R (RN) and w (node rates 3..5) */
            const double *now[2] = {part ? st->RN + 9 * k : st->xN + 3 * k, st->yd + 6 * k + 3 * part};
            const double *want[2] = {part ? s_RN + 9 * k : s_xN + 3 * k, s_yd + 6 * k + 3 * part};
            const int n[2] = {part ? 9 : 3, 3};
            for (int c = 0; c < 2; c++)
                for (int i = 0; i < n[c]; i++)
                    if (fabs(now[c][i] - want[c][i]) > START_MOTION_TOL * fmax(1.0, fabs(want[c][i]))) {
                        snprintf(err, err_len, "the start state (made at build from the scene's initial state) has port "
                                 "%s's %s %s element %d = %.9g, the inputs at t0 give %.9g: set %s's inputs at t0 as "
                                 "the scene's drives give them, or build the FMU from a scene that starts there",
                                 port_names[j < 64 ? j : 63], part ? "rotation" : "translation", c ? "rate" : "value",
                                 i, want[c][i], now[c][i], port_names[j < 64 ? j : 63]);
                        return -1;
                    }
        }
    }
    for (int q = 0, off = 0; q < 10; off += (int)sizes[q], q++)
        memcpy(dst[q], start + off, sizeof(double) * sizes[q]);
    if (ffrf_port_loads_at(b, t0)) {
        snprintf(err, err_len, "out of memory");
        return -1;
    }
    return 0;
}
