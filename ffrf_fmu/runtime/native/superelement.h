/* What superelement.c offers the layers above it: the equations of one superelement and their assembly. */
#ifndef FFRF_SUPERELEMENT_H
#define FFRF_SUPERELEMENT_H

#include "layout.h"

/* ---- superelement.c: the equations of one superelement and their assembly ---- */
/* Bytes of work space one superelement needs (an ffrf_se_work and its arrays, suitably aligned), and
 * that space laid out in `mem` (allocated by body.c at creation, 16-byte aligned). */
size_t ffrf_se_work_bytes(const ffrf_dims *d);
ffrf_se_work *ffrf_se_work_bind(void *mem, const ffrf_dims *d);
/* The numpy path's `_iteration_matrix` (integrator.py): the assembled residual F [ny] with the loads f_load, t_load [N][3] at the
 * stage (p, yd, R [N+E][3][3], theta [N+E][3]) and, if jac, the transposed iteration matrix JT
 * [nf][nf] = (F_ydot + beta [F_y T, F_v])^T on the Newton unknowns (T [N+E][3][3] filled here) in the form factor.c
 * takes: the rows k_q (79) of each superelement premultiplied by M_bar^-1 (its velocity elimination needs them so),
 * each superelement's own blocks set but for J[V, V] (its velocity rows and columns: not read, -beta diag(I, M_bar)
 * by the structure), the boundary nodes' block J[B, B] added into (the caller has zeroed it: ffrf_factor_clear;
 * the entries outside the structure are zero and never written). Fz, Fy: the local blocks, the body's work.Fz,
 * work.Fy (kept by the runtime: cleared only on the rows added into; any other pair is cleared whole). */
void ffrf_evaluate(const ffrf_body *b, ffrf_se_work *w, const double *f_load, const double *t_load,
                   const double *p, const double *yd, const double *R, const double *theta, int jac,
                   double beta, double *F, double *JT, double *Fl, double *Fz, double *Fy, double *T);
/* runtime/equations.py `residual_and_jacobian` of one superelement: the local rows F (nv + nc) of superelement e and, if jac, Fz, Fy
 * [nv + nc][nc + nv]. */
void ffrf_superelement(const ffrf_body *b, int e, const double *p, const double *yd, const double *R,
                       int jac, double *F, double *Fz, double *Fy, ffrf_se_work *w);

#endif
